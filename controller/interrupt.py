r"""Ctrl-C that a control loop cannot lose: a latch checked once per cycle.

Python turns SIGINT into ``KeyboardInterrupt`` at the next bytecode the main thread runs.  When that bytecode
belongs to a finaliser (a ``__del__``, a weakref callback, a garbage-collection callback, which a library
may run at any allocation), Python prints "Exception ignored in …" and drops the exception.  A loop that
stops only on the exception then runs on, and the operator's Ctrl-C is lost.  A run that holds a target
until Ctrl-C (``bellows control`` without ``--duration-s``) would then never end.

:class:`CtrlCLatch` records the request as well as raising.  The loop calls :meth:`CtrlCLatch.check` once
per cycle, and that call raises ``KeyboardInterrupt`` again if the first one was lost.

What the latch takes over, in the main thread (signal handlers can be set only there; elsewhere it does
nothing and :meth:`check` never raises):

* **SIGINT, whatever its disposition**: Python's own handler, the default action, or *ignored* — a process
  started from a non-interactive shell in the background inherits SIGINT ignored, and Python then installs
  no KeyboardInterrupt handler at all: without the latch, a run on a rig started that way could not be
  stopped by SIGINT (``kill -INT``), and a test of the latch silently tested nothing.  A handler of the
  application's own (another latch, a framework's) is kept and chained: it runs first, then the latch
  records the request and raises ``KeyboardInterrupt`` if that handler did not raise.
* **SIGTERM, when it has its default action** (which would kill the process on the spot, leaving drives
  enabled and the run log unclosed): it stops the run like Ctrl-C, through the same safe stop.

Both are restored on exit.  :attr:`CtrlCLatch.signal_name` says which signal stopped the run.
"""

from __future__ import annotations

import signal
import threading


class CtrlCLatch:
    """Context manager: while active, SIGINT (and a default-action SIGTERM) set :attr:`requested` and raise
    ``KeyboardInterrupt``.  ``with CtrlCLatch() as latch: … latch.check() …``"""

    def __init__(self) -> None:
        self.requested = False
        self.signal_name = ""
        self._previous: dict = {}

    def _handler(self, signum, frame) -> None:
        self.requested = True
        self.signal_name = self.signal_name or ("Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name)
        prev = self._previous.get(signum)
        if callable(prev) and prev is not signal.default_int_handler:
            prev(signum, frame)                       # an application's handler first; it may raise itself
        raise KeyboardInterrupt

    def __enter__(self) -> "CtrlCLatch":
        if threading.current_thread() is not threading.main_thread():
            return self
        self._previous[signal.SIGINT] = signal.signal(signal.SIGINT, self._handler)
        if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
            self._previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, self._handler)
        return self

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if a stop was requested since the latch was installed."""
        if self.requested:
            raise KeyboardInterrupt

    def __exit__(self, *exc) -> bool:
        for signum, prev in self._previous.items():
            signal.signal(signum, prev if prev is not None else signal.SIG_DFL)
        self._previous = {}
        return False
