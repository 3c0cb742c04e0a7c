r"""Ctrl-C that a control loop cannot lose: a latch checked once per cycle.

Python turns SIGINT into ``KeyboardInterrupt`` at the next bytecode the main thread runs.  When that bytecode
belongs to a finaliser (a ``__del__``, a weakref callback, a garbage-collection callback, which a library
may run at any allocation), Python prints "Exception ignored in …" and drops the exception.  A loop that
stops only on the exception then runs on, and the operator's Ctrl-C is lost.  A run that holds a target
until Ctrl-C (``bellows control`` without ``--duration-s``) would then never end.

:class:`CtrlCLatch` records the request as well as raising.  The loop calls :meth:`CtrlCLatch.check` once
per cycle, and that call raises ``KeyboardInterrupt`` again if the first one was lost.  The latch is
installed only when SIGINT has Python's own handler and only in the main thread (signal handlers can be set
only there); elsewhere it does nothing and :meth:`check` never raises.
"""

from __future__ import annotations

import signal
import threading


class CtrlCLatch:
    """Context manager: while active, SIGINT sets :attr:`requested` and raises ``KeyboardInterrupt``.

    The previous handler is restored on exit.  ``with CtrlCLatch() as latch: … latch.check() …``
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous = None

    def _handler(self, signum, frame) -> None:
        self.requested = True
        raise KeyboardInterrupt

    def __enter__(self) -> "CtrlCLatch":
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed since the latch was installed."""
        if self.requested:
            raise KeyboardInterrupt

    def __exit__(self, *exc) -> bool:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
        return False
