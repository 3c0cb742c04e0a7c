"""Module-level task functions for the runner tests (picklable for worker processes)."""

import os
import time


def square(task):
    return {"x": task["x"], "y": task["x"] ** 2, "pid": os.getpid()}


def slow(task):
    time.sleep(task["sleep"])
    return {"x": task["x"], "pid": os.getpid()}


def fail_on(task):
    from ancf.errors import InputError
    if task["x"] == task["bad"]:
        raise InputError(f"bad task {task['x']}")
    return task["x"]


def die_on(task):
    """Kills its own worker process (as a segfault or the OOM killer would) for one task."""
    import signal
    if task["x"] == task["bad"]:
        time.sleep(0.5)                       # let the other tasks finish first
        os.kill(os.getpid(), signal.SIGKILL)
    return task["x"]


def pid_and(x):
    """For run_beside: the child's pid and a value."""
    return {"pid": os.getpid(), "x": x}


def raise_convergence(x):
    from ancf.errors import ConvergenceError
    raise ConvergenceError("no", solver="fk", iterations=x, residual_norm=1.0, tolerance=1e-9)


def sleep_long(x):
    time.sleep(x)
    return x


def kill_self(x):
    import signal
    os.kill(os.getpid(), signal.SIGKILL)


def write_niceness_then_sleep(path, seconds=60.0):
    """For in_background: writes the child's pid and niceness, then stays busy until stopped."""
    import pathlib
    pathlib.Path(path).write_text(f"{os.getpid()} {os.nice(0)}")
    time.sleep(seconds)


def thread_pools(task=None):
    """The BLAS / MKL / OpenMP thread-pool sizes this process runs with (threadpoolctl), and its pid."""
    from threadpoolctl import threadpool_info
    return {"pid": os.getpid(), "pools": {i["internal_api"]: i["num_threads"] for i in threadpool_info()}}


def write_thread_pools(path):
    """For in_background: writes :func:`thread_pools` as JSON."""
    import json
    import pathlib
    pathlib.Path(path).write_text(json.dumps(thread_pools()))
