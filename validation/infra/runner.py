"""One task runner for every sweep of the product: the paper's studies and the FEM virtual experiments.

A sweep is a list of independent *tasks* (small picklable records) and one module-level function
``fn(task) -> result``.  :func:`run_tasks` runs them

* in this process (``workers=1``),
* on local processes (default: one per core; ``fork`` where safe, else ``spawn``), or
* on a dask cluster (``scheduler="local"`` for a temporary ``LocalCluster``, an address
  ``"tcp://host:8786"``, or a ``dask.distributed.Client``),

with a progress bar, and hands every result to ``on_result(index, result)`` **as soon as it is done**, so
that a caller can write results incrementally.  Nothing finished is lost:

* Ctrl-C (``KeyboardInterrupt``) cancels the tasks not yet started, terminates the local worker
  processes at once (no worker keeps computing after the interrupt) and raises
  :class:`RunInterrupted`, which carries the results finished so far; callers save them and say where.
* With a :class:`ResultCache`, every finished result is stored on disk under a hash of the task's
  identifying inputs (and of the code that computes it); a re-run takes cached results without computing
  them, so an interrupted sweep resumes where it stopped and a changed input recomputes only what changed.

BLAS threads: worker processes run one BLAS thread each (``OMP_NUM_THREADS`` & co. are set to 1 for
the pool), so that ``n`` workers on ``n`` cores do not oversubscribe them; dask's nanny does the same.
A forked worker inherits the thread pools its parent's BLAS and MKL (PARDISO) libraries already started,
which the variables no longer reach: every child process of this module also limits those pools to one
thread (:func:`limit_threads`, threadpoolctl).  Measured on the quick report's FEM sweep on 2 cores: each
worker had run PARDISO on 2 threads (146 % CPU per worker) and the sweep took 133 s against 105 s with the
limit (docs/fem.md §4).  Results are therefore equal across backends to round-off only (never compare them
bitwise).
"""

from __future__ import annotations

import contextlib
from concurrent.futures.process import BrokenProcessPool
import hashlib
import json
import os
import pathlib
import pickle
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Optional, Sequence

from ancf.errors import BellowsError, InputError

__all__ = ["RunInterrupted", "WorkerDied", "RunOutcome", "ResultCache", "run_tasks", "run_beside", "in_background",
           "source_fingerprint", "task_key", "check_workers"]

_BLAS_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
              "NUMBA_NUM_THREADS")


class RunInterrupted(BellowsError, RuntimeError):
    """A sweep was interrupted (Ctrl-C).  ``completed``: {index: result} of the tasks finished before;
    ``total``: number of tasks; ``saved_to``: where the caller saved them (set by the caller)."""

    def __init__(self, message: str, *, completed: dict[int, Any], total: int, saved_to=None):
        self.completed = completed
        self.total = int(total)
        self.saved_to = saved_to
        super().__init__(message)

    def __str__(self) -> str:
        where = f"; finished results saved to {self.saved_to}" if self.saved_to else ""
        return f"{self.args[0]}: {len(self.completed)} of {self.total} tasks finished{where}"


class WorkerDied(BellowsError, RuntimeError):
    """A worker process died while running a task (a crash in compiled code, or the system killed it, e.g.
    out of memory).  ``completed``: {index: result} of the tasks finished before (already cached when the
    run has a cache); ``total``: number of tasks."""

    def __init__(self, message: str, *, completed: dict[int, Any], total: int):
        self.completed = completed
        self.total = int(total)
        super().__init__(message)


@dataclass
class RunOutcome:
    """What :func:`run_tasks` returns.

    results : list, one per task in task order
    backend : description ("serial (this process)", "processes (fork)", "dask (tcp://...)")
    workers : number of workers used
    cached : number of results taken from the cache (not computed)
    seconds : wall-clock time [s]
    """
    results: list
    backend: str
    workers: int
    cached: int = 0
    seconds: float = 0.0
    computed_indices: list = field(default_factory=list)


# ------------------------------------------------------------------------------------------ cache
def _canonical(x: Any) -> Any:
    """A JSON-able canonical form of a task's identifying inputs (floats by repr, arrays as lists)."""
    import numpy as np
    if isinstance(x, dict):
        return {str(k): _canonical(v) for k, v in sorted(x.items(), key=lambda kv: str(kv[0]))}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if isinstance(x, np.ndarray):
        return {"__array__": _canonical(x.tolist()), "shape": list(x.shape)}
    if isinstance(x, (np.floating, float)):
        return repr(float(x))
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if hasattr(x, "model_dump"):               # pydantic models (ActuatorParams, ...)
        return _canonical(x.model_dump())
    if hasattr(x, "__dataclass_fields__"):
        return _canonical({k: getattr(x, k) for k in x.__dataclass_fields__})
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    if isinstance(x, pathlib.Path):
        return str(x)
    raise InputError(f"cannot hash a task input of type {type(x).__name__} ({x!r:.60})")


def task_key(inputs: Any, version: str = "") -> str:
    """SHA-256 hex digest of a task's identifying ``inputs`` (any nesting of dicts, lists, numbers,
    strings, arrays, dataclasses, pydantic models) and a code ``version`` string."""
    blob = json.dumps({"inputs": _canonical(inputs), "version": version}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()


def source_fingerprint(*packages: str, exclude: Sequence[str] = (), files: Sequence[str] = ()) -> str:
    """A short hash of the Python sources of the named packages (e.g. ``"fem_reference"``) and of further
    modules (``files``: dotted names, e.g. ``"validation.reference.fem_sweep"``): cached results are recomputed when the
    code that produced them changes.  ``exclude``: file names (relative to a package, e.g. ``"cli.py"``) that
    cannot change a result (presentation only)."""
    import importlib
    h = hashlib.sha256()
    for name in packages:
        mod = importlib.import_module(name)
        root = pathlib.Path(mod.__file__).parent
        for path in sorted(root.rglob("*.py")):
            rel = str(path.relative_to(root))
            if rel in exclude:
                continue
            h.update(rel.encode())
            h.update(path.read_bytes())
    for name in files:
        path = pathlib.Path(importlib.import_module(name).__file__)
        h.update(name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def check_workers(workers) -> None:
    """``workers`` is None (all cores) or a positive integer; InputError otherwise."""
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool) or workers < 1):
        raise InputError(f"workers must be a positive integer, got {workers!r}")


class ResultCache:
    """Results on disk, one file per task, named by :func:`task_key` (``<key>.pkl``), written atomically
    (temporary file + rename: a crash never leaves a half-written entry).  ``index.jsonl`` in the same
    folder lists each key with its inputs, for people."""

    def __init__(self, directory, version: str = ""):
        self.dir = pathlib.Path(directory)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create the cache folder {self.dir}: {exc}") from None
        if not os.access(self.dir, os.W_OK):
            raise InputError(f"cache folder {self.dir} is not writable")
        self.version = version

    def key(self, inputs) -> str:
        return task_key(inputs, self.version)

    def _path(self, key: str) -> pathlib.Path:
        return self.dir / f"{key}.pkl"

    def get(self, key: str, default=None):
        path = self._path(key)
        try:
            with open(path, "rb") as fh:
                return pickle.load(fh)
        except FileNotFoundError:
            return default
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError):
            return default      # unreadable entry (older code, truncated by a dead disk): recompute

    def __contains__(self, key: str) -> bool:
        return self._path(key).exists()

    def put(self, key: str, result, inputs=None) -> None:
        path = self._path(key)
        tmp = path.with_suffix(f".tmp{os.getpid()}")
        with open(tmp, "wb") as fh:
            pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        if inputs is not None:
            with open(self.dir / "index.jsonl", "a") as fh:
                fh.write(json.dumps({"key": key, "version": self.version, "inputs": _canonical(inputs)}) + "\n")


# ------------------------------------------------------------------------------------------ running
def _start_method() -> str:
    """``fork`` where the platform has it and this process runs no other thread (fast; works from scripts
    without a ``__main__`` guard); else ``spawn`` (needs the guard)."""
    import multiprocessing as mp
    import threading
    if "fork" in mp.get_all_start_methods() and threading.active_count() == 1:
        return "fork"
    return "spawn"


def limit_threads() -> None:
    """One thread for this process's BLAS, MKL and OpenMP pools: the variables for libraries loaded from now
    on, threadpoolctl for those already loaded (a forked child inherits its parent's pools, e.g. MKL's after
    the parent ran PARDISO)."""
    from threadpoolctl import threadpool_limits
    for var in _BLAS_VARS[:-1]:
        os.environ[var] = "1"
    threadpool_limits(1)


@contextlib.contextmanager
def _single_thread_env():
    """BLAS thread variables = 1 while worker processes are started (spawned workers inherit them)."""
    old = {v: os.environ.get(v) for v in _BLAS_VARS[:-1]}
    for v in old:
        os.environ[v] = "1"
    try:
        yield
    finally:
        for v, val in old.items():
            if val is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = val


class PlainProgress:
    """Progress as plain lines on a stream, for output that is not a terminal (a log file, a pipe, CI):
    ``description: k/N (P %) after E s, about R s left`` at most every ``every_s`` seconds and at the end.
    The subset of :class:`rich.progress.Progress` that :func:`run_tasks` uses."""

    def __init__(self, stream=None, every_s: float = 10.0, clock: Callable[[], float] = time.monotonic):
        self.stream, self.every_s, self.clock = stream, every_s, clock
        self.tasks: dict[int, dict] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        for tid, t in self.tasks.items():
            if t["printed"] != t["completed"]:
                self._line(tid)

    def add_task(self, description: str, total: float, completed: float = 0.0) -> int:
        tid = len(self.tasks)
        now = self.clock()
        self.tasks[tid] = dict(description=description, total=float(total), completed=float(completed),
                               start=now, start_completed=float(completed), last=now, printed=None)
        return tid

    def update(self, tid: int, advance: float = 0.0) -> None:
        t = self.tasks[tid]
        t["completed"] += advance
        if self.clock() - t["last"] >= self.every_s or t["completed"] >= t["total"]:
            self._line(tid)

    def _line(self, tid: int) -> None:
        t = self.tasks[tid]
        now = self.clock()
        elapsed, done, total = now - t["start"], t["completed"], t["total"]
        rate_done = done - t["start_completed"]
        pct = 100 * done / total if total else 100.0
        line = f"{t['description']}: {done:g}/{total:g} ({pct:.0f} %) after {elapsed:.0f} s"
        if 0 < rate_done and done < total:
            line += f", about {elapsed / rate_done * (total - done):.0f} s left"
        stream = self.stream or sys.stderr
        stream.write(line + "\n")
        stream.flush()
        t["last"], t["printed"] = now, done


def _progress_bar(enabled: bool, description: str, total: int):
    """A rich progress bar on a terminal; plain progress lines on stderr where stdout is not one."""
    if enabled and not sys.stdout.isatty():
        return PlainProgress()
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)
    bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TimeElapsedColumn(), TimeRemainingColumn(), disable=not enabled, transient=False)
    return bar


def _kill_pool(pool) -> None:
    """Stop a ProcessPoolExecutor now: cancel queued tasks and terminate its worker processes."""
    procs = list(getattr(pool, "_processes", {}).values() or [])
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    deadline = time.monotonic() + 5.0
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()


def run_tasks(fn: Callable[[Any], Any], tasks: Sequence[Any], *, workers: Optional[int] = None,
              scheduler=None, progress: bool = True, description: str = "tasks",
              on_result: Optional[Callable[[int, Any], None]] = None,
              cache: Optional[ResultCache] = None, key_inputs: Optional[Callable[[Any], Any]] = None,
              start_method: Optional[str] = None, weights: Optional[Sequence[float]] = None) -> RunOutcome:
    """Run ``fn`` over ``tasks``; see the module docstring.

    Parameters
    ----------
    fn : module-level function (picklable), ``fn(task) -> result``
    tasks : sequence of picklable task records
    workers : local worker processes (default: all cores, at most the number of tasks; 1 = this process);
        with ``scheduler="local"`` the number of dask workers
    scheduler : None | "local" | "tcp://address" | dask.distributed.Client
    progress : show progress (a rich bar on a terminal, else plain lines on stderr every 10 s)
    on_result : called in this process as ``on_result(index, result)`` once per task, in completion
        order, also for cached results (first, in task order)
    cache : a :class:`ResultCache`; ``key_inputs(task)`` gives the identifying inputs hashed into the key
        (default: the task itself)
    weights : relative cost per task for the progress bar (default 1 each)

    Raises
    ------
    RunInterrupted
        On Ctrl-C, after stopping every worker; ``.completed`` holds the finished results.
    BellowsError subclasses raised by ``fn`` propagate unchanged (the other workers are stopped first).
    """
    if not callable(fn):
        raise InputError("run_tasks: fn must be callable")
    tasks = list(tasks)
    n = len(tasks)
    check_workers(workers)
    w = [1.0] * n if weights is None else [float(x) for x in weights]
    if len(w) != n:
        raise InputError("weights must have one entry per task")
    t0 = time.perf_counter()
    results: dict[int, Any] = {}
    keys: dict[int, str] = {}
    cached = 0
    if cache is not None:
        for i, t in enumerate(tasks):
            k = cache.key(t if key_inputs is None else key_inputs(t))
            keys[i] = k
            hit = cache.get(k)
            if hit is not None:
                results[i] = hit
                cached += 1
                if on_result is not None:
                    on_result(i, hit)
    todo = [i for i in range(n) if i not in results]

    def record(i: int, res) -> None:
        results[i] = res
        if cache is not None:
            cache.put(keys[i], res, None if key_inputs is None else key_inputs(tasks[i]))
        if on_result is not None:
            on_result(i, res)

    backend, nworkers = "serial (this process)", 1
    with _progress_bar(progress, description, n) as bar:
        bid = bar.add_task(description, total=sum(w), completed=sum(w[i] for i in results))

        def done(i, res):
            record(i, res)
            bar.update(bid, advance=w[i])

        try:
            if not todo:
                pass
            elif scheduler is not None:
                backend, nworkers = _run_dask(fn, tasks, todo, workers, scheduler, done)
            else:
                nworkers = (os.cpu_count() or 1) if workers is None else workers
                nworkers = max(1, min(nworkers, len(todo)))
                if nworkers == 1:
                    for i in todo:
                        done(i, fn(tasks[i]))
                else:
                    method = start_method or _start_method()
                    backend = f"processes ({method})"
                    _run_pool(fn, tasks, todo, nworkers, method, done)
        except KeyboardInterrupt:
            raise RunInterrupted(f"{description} interrupted", completed=dict(results), total=n) from None
        except BrokenProcessPool as exc:
            kept = "; they are cached: a re-run computes only the rest" if cache is not None else ""
            raise WorkerDied(f"{description}: a worker process died (a crash or the system killed it, e.g. out of "
                             f"memory) after {len(results)} of {n} tasks had finished{kept}; run with one worker "
                             f"(--workers 1) to see the failing task's error in this process",
                             completed=dict(results), total=n) from exc
    return RunOutcome([results[i] for i in range(n)], backend, nworkers, cached, time.perf_counter() - t0,
                      computed_indices=todo)


def _daemon_child(target, *args):
    """A started daemon process running ``target(*args)`` (fork where safe; BLAS threads = 1)."""
    import multiprocessing as mp
    with _single_thread_env():
        child = mp.get_context(_start_method()).Process(target=target, args=args, daemon=True)
        child.start()
    return child


def _stop(child) -> None:
    """Terminate ``child`` if it still runs, and reap it."""
    if child.is_alive():
        child.terminate()
    child.join(5.0)


def _beside_child(conn, fn, kwargs) -> None:
    try:
        limit_threads()
        out = ("ok", fn(**kwargs))
    except BaseException as exc:          # noqa: BLE001 - handed to the parent, which raises it
        out = ("error", exc)
    try:
        conn.send(out)
    except Exception as exc:              # noqa: BLE001 - an unpicklable result: say so rather than hang
        conn.send(("error", RuntimeError(f"run_beside: the result of {getattr(fn, '__name__', fn)} could not be "
                                         f"sent back: {exc}")))
    conn.close()


def run_beside(fn: Callable[..., Any], kwargs: dict, work: Callable[[], Any]) -> tuple[Any, Any]:
    """``fn(**kwargs)`` in one worker process while ``work()`` runs in this one → ``(fn's result, work's
    result)``.  For a serial computation that can overlap a parallel one (the model fits while the FEM's
    refined solves run): ``work`` may itself start worker processes with :func:`run_tasks` — the child is a
    plain process, so this process keeps no extra thread and ``run_tasks`` still forks.  An exception in
    ``fn`` is raised here (after ``work`` finished); a Ctrl-C or an error in ``work`` stops the child at
    once; a child that dies raises :class:`WorkerDied`.  The child is a daemon process: ``fn`` must not start
    processes of its own."""
    if not callable(fn) or not callable(work) or not isinstance(kwargs, dict):
        raise InputError("run_beside: fn and work must be callable and kwargs a dict")
    import multiprocessing as mp
    here, there = mp.get_context(_start_method()).Pipe(duplex=False)
    child = _daemon_child(_beside_child, there, fn, kwargs)
    there.close()
    try:
        side = work()
        try:
            status, value = here.recv()
        except EOFError:
            raise WorkerDied(f"the worker process running {getattr(fn, '__name__', fn)} died (a crash, or the "
                             "system killed it, e.g. out of memory)", completed={}, total=1) from None
        child.join()
    finally:
        here.close()
        _stop(child)
    if status == "error":
        raise value
    return value, side


def _background_child(fn, nice: int) -> None:
    try:
        if nice and hasattr(os, "nice"):
            os.nice(nice)
        limit_threads()
        fn()
    except BaseException:                 # noqa: BLE001 - what it did not finish, the caller does itself
        pass


@contextlib.contextmanager
def in_background(fn: Callable[[], Any], *, nice: int = 19):
    """``with in_background(fn): …`` runs ``fn()`` in a daemon child process at low CPU priority (``nice``
    added to this process's niceness; 19: it takes only a core nothing else wants) while the block runs, and
    stops it when the block ends, finished or not.  Only for work whose product is left behind and that the
    caller would otherwise do itself: numba's on-disk cache of compiled kernels, filled while the FEM sweep
    leaves a core idle (:func:`validation.identification.identify.compile_fit_kernels`).  Its result and errors are dropped.
    Yields the child process."""
    if not callable(fn):
        raise InputError("in_background: fn must be callable")
    if isinstance(nice, bool) or not isinstance(nice, int) or not 0 <= nice <= 19:
        raise InputError(f"in_background: nice must be an integer in [0, 19], got {nice!r}")
    child = _daemon_child(_background_child, fn, nice)
    try:
        yield child
    finally:
        _stop(child)


def _run_pool(fn, tasks, todo, nworkers, method, done) -> None:
    import concurrent.futures as cf
    import multiprocessing as mp
    pool = None
    try:   # a Ctrl-C while the workers start or the tasks are submitted must stop them too (else exit waits)
        with _single_thread_env():
            pool = cf.ProcessPoolExecutor(max_workers=nworkers, mp_context=mp.get_context(method),
                                          initializer=limit_threads)
            futs = {pool.submit(fn, tasks[i]): i for i in todo}
        for f in cf.as_completed(futs):
            done(futs[f], f.result())
    except BaseException:
        if pool is not None:
            _kill_pool(pool)
        raise
    pool.shutdown(wait=True)


def _run_dask(fn, tasks, todo, workers, scheduler, done) -> tuple[str, int]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError("a dask scheduler was given but dask.distributed is not installed "
                         "(pip install 'bellows[distributed]')") from None
    with contextlib.ExitStack() as stack:
        if isinstance(scheduler, Client):
            client, where = scheduler, str(getattr(scheduler.scheduler, "address", "?"))
        elif scheduler == "local":
            cluster = stack.enter_context(LocalCluster(n_workers=workers or os.cpu_count() or 1,
                                                       threads_per_worker=1, processes=True,
                                                       dashboard_address=None))
            client, where = stack.enter_context(Client(cluster)), "temporary LocalCluster"
        elif isinstance(scheduler, str):
            try:
                client = stack.enter_context(Client(scheduler, timeout="10s"))
            except (OSError, TimeoutError) as exc:
                raise InputError(f"cannot reach the dask scheduler at {scheduler!r}: {exc}") from None
            where = scheduler
        else:
            raise InputError(f"scheduler must be None, 'local', an address or a dask Client, got {scheduler!r}")
        nworkers = len(client.scheduler_info().get("workers", {}))
        futs = client.map(fn, [tasks[i] for i in todo], pure=False)
        index = {f.key: i for f, i in zip(futs, todo)}
        try:
            for f in as_completed(futs):
                done(index[f.key], f.result())
        except BaseException:
            client.cancel(futs)
            raise
        return f"dask ({where})", nworkers


def iter_chunks(items: Sequence, size: int) -> Iterable[Sequence]:
    """Consecutive slices of ``items`` of length ``size`` (the last one shorter)."""
    if size < 1:
        raise InputError(f"chunk size must be >= 1, got {size}")
    for k in range(0, len(items), size):
        yield items[k:k + size]
