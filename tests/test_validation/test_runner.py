"""The shared task runner: backends agree, results stream, the cache resumes, Ctrl-C keeps finished work."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from ancf.errors import BellowsError, InputError
from validation.infra.runner import ResultCache, RunInterrupted, run_tasks, task_key

import _runner_tasks as T


def _default_sigint():
    """In the child: SIGINT back to its default, so Python installs its KeyboardInterrupt handler even when this
    test runs from a shell that started it in the background (which leaves SIGINT ignored in every child)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_serial_and_processes_agree_and_stream_every_result():
    tasks = [{"x": k} for k in range(7)]
    seen = []
    a = run_tasks(T.square, tasks, workers=1, progress=False)
    b = run_tasks(T.square, tasks, workers=2, progress=False, on_result=lambda i, r: seen.append(i))
    assert [r["y"] for r in a.results] == [k * k for k in range(7)]
    assert [r["y"] for r in b.results] == [r["y"] for r in a.results]
    assert sorted(seen) == list(range(7))
    assert b.backend.startswith("processes") and a.backend.startswith("serial")
    assert {r["pid"] for r in a.results} == {os.getpid()}
    assert os.getpid() not in {r["pid"] for r in b.results}            # computed in worker processes


def test_two_workers_share_the_work():
    """Tasks that each take 0.3 s are spread over both workers (not run one after another in one)."""
    tasks = [{"x": k, "sleep": 0.3} for k in range(6)]
    b = run_tasks(T.slow, tasks, workers=2, progress=False)
    assert [r["x"] for r in b.results] == list(range(6))
    assert len({r["pid"] for r in b.results}) == 2 and os.getpid() not in {r["pid"] for r in b.results}


def test_cache_skips_finished_tasks_and_recomputes_changed_ones(tmp_path):
    cache = ResultCache(tmp_path / "c", version="v1")
    tasks = [{"x": k} for k in range(4)]
    first = run_tasks(T.square, tasks, workers=1, progress=False, cache=cache)
    assert first.cached == 0 and first.computed_indices == [0, 1, 2, 3]
    tasks[2] = {"x": 10}
    second = run_tasks(T.square, tasks, workers=1, progress=False, cache=cache)
    assert second.cached == 3 and second.computed_indices == [2]
    assert second.results[2]["y"] == 100
    # another code version invalidates everything
    third = run_tasks(T.square, tasks, workers=1, progress=False, cache=ResultCache(tmp_path / "c", version="v2"))
    assert third.cached == 0


def test_task_key_is_canonical_and_sensitive():
    import numpy as np
    assert task_key({"a": 1.0, "b": [1, 2]}) == task_key({"b": [1, 2], "a": 1.0})
    assert task_key({"a": np.array([1.0, 2.0])}) != task_key({"a": np.array([1.0, 2.0 + 1e-12])})
    with pytest.raises(InputError):
        task_key({"a": object()})


def test_task_errors_propagate_typed():
    with pytest.raises(InputError, match="bad task 3"):
        run_tasks(T.fail_on, [{"x": k, "bad": 3} for k in range(5)], workers=2, progress=False)


def test_bad_arguments_are_typed_errors():
    with pytest.raises(InputError):
        run_tasks(T.square, [{"x": 1}], workers=0, progress=False)
    with pytest.raises(InputError):
        run_tasks(T.square, [{"x": 1}], weights=[1, 2], progress=False)


def test_ctrl_c_stops_workers_promptly_and_keeps_finished_results(tmp_path):
    """SIGINT to a running 2-worker sweep: it returns within seconds, the finished results are saved, and no
    worker process survives."""
    out = tmp_path / "done.json"
    script = textwrap.dedent(f"""
        import json, sys
        sys.path.insert(0, {str(os.path.dirname(__file__))!r})
        import _runner_tasks as T
        from validation.infra.runner import run_tasks, RunInterrupted
        tasks = [{{"x": k, "sleep": 0.2 if k < 4 else 30.0}} for k in range(12)]
        try:
            run_tasks(T.slow, tasks, workers=2, progress=False)
        except RunInterrupted as exc:
            pids = [r["pid"] for r in exc.completed.values()]
            json.dump({{"done": sorted(exc.completed), "total": exc.total, "pids": pids}}, open({str(out)!r}, "w"))
            sys.exit(3)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=os.getcwd(),
                            preexec_fn=_default_sigint)  # noqa: PLW1509 (only resets a signal)
    time.sleep(4.0)          # the 4 short tasks are done, two 30 s tasks are running
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    rc = proc.wait(timeout=20)
    assert time.monotonic() - t0 < 10
    assert rc == 3
    data = json.loads(out.read_text())
    assert data["total"] == 12 and set(range(4)) <= set(data["done"]) and len(data["done"]) < 12
    for pid in set(data["pids"]):        # workers are gone
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_run_interrupted_is_a_bellows_error():
    exc = RunInterrupted("sweep interrupted", completed={0: 1}, total=3, saved_to="x.json")
    assert isinstance(exc, BellowsError) and "1 of 3" in str(exc) and "x.json" in str(exc)


def test_dask_scheduler_address_gives_the_serial_results(tmp_path):
    """``--scheduler ADDRESS``: the tasks run on a dask cluster reached by its address, results in order, and
    the cache is filled as on local cores."""
    distributed = pytest.importorskip("dask.distributed")
    tasks = [{"x": k} for k in range(5)]
    serial = run_tasks(T.square, tasks, workers=1, progress=False)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        out = run_tasks(T.square, tasks, scheduler=cluster.scheduler_address, progress=False,
                        cache=ResultCache(tmp_path, "v1"))
    assert out.backend.startswith("dask") and cluster.scheduler_address in out.backend
    assert [r["y"] for r in out.results] == [r["y"] for r in serial.results]
    assert len(list(tmp_path.glob("*.pkl"))) == len(tasks)


def test_unreachable_dask_scheduler_is_a_typed_error():
    pytest.importorskip("dask.distributed")
    with pytest.raises(BellowsError, match="cannot reach the dask scheduler"):
        run_tasks(T.square, [{"x": 1}], scheduler="tcp://127.0.0.1:9", progress=False)


def test_plain_progress_lines_while_running_not_only_at_the_end():
    """Where stdout is not a terminal, progress is plain lines as the run goes (throttled by the clock)."""
    import io

    from validation.infra.runner import PlainProgress
    now = [0.0]
    out = io.StringIO()
    with PlainProgress(stream=out, every_s=10.0, clock=lambda: now[0]) as bar:
        tid = bar.add_task("FEM cases", total=4, completed=1)     # one from the cache
        now[0] = 5.0
        bar.update(tid, advance=1)                                 # < 10 s since the start: quiet
        assert out.getvalue() == ""
        now[0] = 20.0
        bar.update(tid, advance=1)                                 # 3/4 after 20 s: 2 computed -> 10 s each
        assert out.getvalue().splitlines() == ["FEM cases: 3/4 (75 %) after 20 s, about 10 s left"]
        now[0] = 21.0
        bar.update(tid, advance=1)                                 # the last one is always printed
    lines = out.getvalue().splitlines()
    assert lines[-1] == "FEM cases: 4/4 (100 %) after 21 s" and len(lines) == 2


def test_run_tasks_prints_plain_progress_to_stderr_when_piped(tmp_path):
    code = textwrap.dedent("""
        import sys
        sys.path.insert(0, %r)
        import _runner_tasks as T
        from validation.infra.runner import run_tasks
        out = run_tasks(T.square, [{"x": k} for k in range(3)], workers=1, progress=True, description="squares")
        print("results", [r["y"] for r in out.results])
    """ % os.path.dirname(__file__))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "results [0, 1, 4]"               # stdout stays clean for data
    assert "squares: 3/3 (100 %)" in res.stderr and "\x1b[" not in res.stderr


def test_source_fingerprint_follows_computing_code_only(tmp_path, monkeypatch):
    """Editing a presentation module keeps cached results; editing computing code (or an extra module) does not."""
    from validation.infra.runner import source_fingerprint
    pkg = tmp_path / "fpkg_demo"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "model.py").write_text("K = 1\n")
    (pkg / "cli.py").write_text("HELP = 'a'\n")
    (tmp_path / "fextra_demo.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))

    def fp():
        return source_fingerprint("fpkg_demo", exclude=("cli.py",), files=("fextra_demo",))
    a = fp()
    (pkg / "cli.py").write_text("HELP = 'b'\n")
    assert fp() == a
    (pkg / "model.py").write_text("K = 2\n")
    b = fp()
    assert b != a
    (tmp_path / "fextra_demo.py").write_text("X = 2\n")
    assert fp() != b


def test_a_dying_worker_is_a_typed_error_that_keeps_finished_results(tmp_path):
    """A worker killed mid-task (segfault, OOM killer) ends the run with WorkerDied, not BrokenProcessPool; the
    results finished before are kept (and cached), so a re-run computes only the rest."""
    from validation.infra.runner import WorkerDied
    tasks = [{"x": k, "bad": 3} for k in range(4)]
    cache = ResultCache(tmp_path / "cache", version="t")
    with pytest.raises(WorkerDied) as info:
        run_tasks(T.die_on, tasks, workers=2, progress=False, cache=cache)
    assert isinstance(info.value, BellowsError) and info.value.total == 4
    assert 3 not in info.value.completed and len(info.value.completed) >= 1
    assert "--workers 1" in str(info.value) and "cached" in str(info.value)
    again = run_tasks(T.square, [{"x": k} for k in range(2)], workers=1, progress=False)   # the runner still works
    assert [r["y"] for r in again.results] == [0, 1]


def test_fem_cache_version_covers_every_module_that_computes_a_cached_result(monkeypatch):
    """Cached FEM records hold numbers computed in validation/ too (the sweep worker, rod measures, locked
    compliance, the load cases, the modes per pressure): each of those modules must be hashed into the cache
    version, or an edit to them would serve stale results."""
    import validation.reference.fem_sweep as fs
    seen = {}
    monkeypatch.setattr(fs, "source_fingerprint",
                        lambda pkg, exclude=(), files=(): seen.update(pkg=pkg, files=set(files)) or "x")
    fs.fem_fingerprint()
    assert seen["pkg"] == "fem_reference"
    for fn in (fs.solve_task, fs.solve_chain, fs.rod_estimate, fs.locked_compliance, fs.LoadCase, fs.modes_chain,
               fs.classify_fem_modes):
        assert fn.__module__ in seen["files"], fn.__qualname__


def test_run_beside_runs_the_function_in_another_process_while_the_work_forks_its_own():
    import threading

    from validation.infra.runner import run_beside
    before = set(threading.enumerate())

    def work():      # no thread of run_beside's in this process (run_tasks forks when there is none)
        return set(threading.enumerate()), run_tasks(T.square, [{"x": k} for k in range(4)], workers=2,
                                                     progress=False)

    value, (threads, side) = run_beside(T.pid_and, {"x": 3}, work)
    assert value["x"] == 3 and value["pid"] != os.getpid()
    assert not threads - before
    assert [r["y"] for r in side.results] == [0, 1, 4, 9] and side.backend.startswith("processes")


def test_run_beside_raises_the_childs_error_as_itself_and_stops_the_child_on_a_failing_work():
    from ancf.errors import ConvergenceError
    from validation.infra.runner import WorkerDied, run_beside
    with pytest.raises(ConvergenceError) as info:
        run_beside(T.raise_convergence, {"x": 7}, lambda: None)
    assert info.value.iterations == 7
    t0 = time.monotonic()
    with pytest.raises(InputError, match="work failed"):
        run_beside(T.sleep_long, {"x": 60}, lambda: (_ for _ in ()).throw(InputError("work failed")))
    assert time.monotonic() - t0 < 10                    # the 60 s child was stopped, not waited for
    with pytest.raises(WorkerDied):
        run_beside(T.kill_self, {"x": 0}, lambda: None)
    with pytest.raises(InputError):
        run_beside(T.pid_and, [3], lambda: None)


def test_in_background_runs_at_low_priority_and_stops_with_the_block(tmp_path):
    """The child runs the function at niceness + 19 while the block runs and is gone once the block ends
    (finished or not: here it would sleep for a minute)."""
    import functools
    from validation.infra.runner import in_background
    out = tmp_path / "nice.txt"
    with in_background(functools.partial(T.write_niceness_then_sleep, out)) as child:
        t0 = time.monotonic()
        while not out.exists() and time.monotonic() - t0 < 30:
            time.sleep(0.05)
        pid, nice = map(int, out.read_text().split())
        assert child.is_alive() and pid == child.pid != os.getpid()
        assert nice == min(19, os.nice(0) + 19)
    assert not child.is_alive()
    with pytest.raises(InputError, match="callable"):
        with in_background("not a function"):
            pass
    for bad in (-1, 20, 2.5, True):
        with pytest.raises(InputError, match="nice"):
            with in_background(time.time, nice=bad):
                pass


def test_every_child_runs_one_thread_per_pool_even_when_forked_from_a_multithreaded_parent(tmp_path):
    """A forked child inherits the thread pools its parent's BLAS (and MKL, after a PARDISO solve) already
    started, which the environment variables no longer reach: run_tasks' workers, run_beside's child and
    in_background's child each limit them to one thread (on 2 cores, two FEM workers with 2-thread PARDISO
    took 133 s for the quick report's sweep against 105 s; docs/fem.md §4)."""
    import functools
    import json

    from threadpoolctl import threadpool_limits

    from validation.infra.runner import in_background, run_beside
    with threadpool_limits(2):
        parent = T.thread_pools()["pools"]
        if not parent or max(parent.values()) < 2:
            pytest.skip(f"the thread pools here cannot run 2 threads: {parent}")
        workers = run_tasks(T.thread_pools, [{}, {}], workers=2, progress=False)
        assert workers.backend.startswith("processes")
        side, _ = run_beside(T.thread_pools, {}, lambda: None)
        out = tmp_path / "pools.json"
        with in_background(functools.partial(T.write_thread_pools, out), nice=0):
            t0 = time.monotonic()
            while not out.exists() and time.monotonic() - t0 < 30:
                time.sleep(0.05)
        background = json.loads(out.read_text())
    forked = workers.backend == "processes (fork)"
    for child in [*workers.results, side, background]:
        assert child["pid"] != os.getpid()
        assert all(n == 1 for n in child["pools"].values()), child
    # forked workers hold every pool of the parent (a spawned child — chosen when this process runs other threads —
    # loads only what it imports, and the environment variables reach those)
    assert not forked or all(set(w["pools"]) == set(parent) for w in workers.results), (workers.backend, parent)
