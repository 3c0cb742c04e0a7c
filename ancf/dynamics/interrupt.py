r"""Ctrl-C during a transient run: a flag checked between steps, never an exception inside a compiled kernel.

Python turns SIGINT into ``KeyboardInterrupt`` at the next bytecode the main thread runs.  When that happens
while a numba-compiled function is being called (the assembly of every Newton iteration), the dispatcher
returns with an exception set and CPython reports a ``SystemError`` instead — the run's rows were lost, and
the caller saw no interrupt at all.  :class:`StopFlag` replaces Python's SIGINT handler for the duration of
the run by one that only records the request (:attr:`StopFlag.requested`); the time loop reads the flag
between steps, in Python, and ends the run there with the rows done.

Rules (main thread only: signal handlers can be set nowhere else; in another thread the flag does nothing
and a ``KeyboardInterrupt`` is handled as before):

* Python's own handler (``signal.default_int_handler``) is replaced; a SIGINT that is ignored (``SIG_IGN``,
  e.g. a process started in the background by a non-interactive shell) or left at the default action
  (``SIG_DFL``) is left as it is: the run does not take over what its process chose.
* An application's own handler (a control loop's latch) is replaced too, and after the run — its handler
  restored — it is called once if a SIGINT arrived, so the application sees its Ctrl-C, raised in Python
  code outside any kernel.
* The previous handler is always restored when the run ends, however it ends.
"""

from __future__ import annotations

import signal
import threading


class StopFlag:
    """Context manager: while active, SIGINT sets :attr:`requested` instead of raising (module docstring)."""

    def __init__(self) -> None:
        self.requested = False
        self._previous = None
        self._installed = False

    def _handler(self, signum, frame) -> None:
        self.requested = True

    def __enter__(self) -> "StopFlag":
        if threading.current_thread() is not threading.main_thread():
            return self
        prev = signal.getsignal(signal.SIGINT)
        if callable(prev):                    # Python's KeyboardInterrupt handler or an application's
            self._previous = signal.signal(signal.SIGINT, self._handler)
            self._installed = True
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if not self._installed:
            return False
        signal.signal(signal.SIGINT, self._previous)
        self._installed = False
        prev = self._previous
        if self.requested and exc_type is None and prev is not signal.default_int_handler:
            prev(signal.SIGINT, None)         # the application's handler sees its Ctrl-C (it may raise)
        return False
