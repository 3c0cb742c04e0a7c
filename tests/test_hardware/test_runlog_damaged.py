"""Damaged run logs: a truncated or corrupt log is a typed error within a bounded time (never a hang —
every reader runs in a subprocess with a timeout, so the test itself cannot hang); missing groups and
malformed attributes are clear errors; an empty log has a summary; a torn (half-written) last row reads
as NaN, and a torn static state does not lose the finished ones."""

import os
import pathlib
import subprocess
import sys
import textwrap

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")

from ancf.errors import ConfigError  # noqa: E402
from hardware.runlog import RunLog, export_csv, read_run_log, summary  # noqa: E402
from hardware.static_states import read_static_states  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
TIMEOUT_S = 30                    # generous on a loaded machine: a working reader answers in a second or two


def write_log(path, rows=40, static=2, kill=False):
    """A run log with ``rows`` samples and ``static`` static states; ``kill``: the writer is SIGKILLed
    before closing it (in a subprocess), as a crashed run leaves it."""
    code = textwrap.dedent(f"""
        import os, signal
        from hardware.runlog import RunLog
        log = RunLog({str(path)!r}, n_tendons=3, run={{"target_m": [0.17, 0.0, 0.0], "pressure_Pa": 6e4}})
        for k in range({rows}):
            log.sample(t=0.1 * k, iteration=k, tip=[0.17, 0.0, 0.001 * k], error_norm=1e-3 * k,
                       tension=[1.0, 2.0, 3.0])
            log.event(0.1 * k, "note", f"row {{k}}")
        for k in range({static}):
            log.static_state(time=k, tensions=[1.0, 2.0, 3.0], pressure=6e4, tip=[0.17, 0.0, 0.001 * k])
        if {kill}:
            log.flush()                     # what a running loop's block flushes have written by then
            os.kill(os.getpid(), signal.SIGKILL)
        log.close()
    """)
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                   timeout=TIMEOUT_S, check=not kill)
    assert path.exists()
    return path


def read_in_subprocess(call: str, path) -> subprocess.CompletedProcess:
    """Run ``call(path)`` in a fresh interpreter; prints ``OK`` or ``<ErrorType>: message`` (exit 3)."""
    code = textwrap.dedent(f"""
        import sys
        from hardware.runlog import read_run_log, summary, export_csv
        from hardware.static_states import read_static_states
        try:
            {call}({str(path)!r})
        except Exception as exc:
            print(f"{{type(exc).__module__}}.{{type(exc).__name__}}: {{exc}}")
            sys.exit(3)
        print("OK")
    """)
    try:
        return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                              capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{call} on {path.name} did not return within {TIMEOUT_S} s (hangs)")


def truncate(src, dst, fraction):
    data = pathlib.Path(src).read_bytes()
    pathlib.Path(dst).write_bytes(data[:int(len(data) * fraction)])
    return pathlib.Path(dst)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    return {"finished": write_log(d / "finished.h5"), "killed": write_log(d / "killed.h5", kill=True)}


@pytest.mark.parametrize("which", ["finished", "killed"])
@pytest.mark.parametrize("fraction", [0.3, 0.8])
@pytest.mark.parametrize("call", ["summary", "read_static_states"])
def test_truncated_log_is_a_typed_error_not_a_hang(logs, tmp_path, which, fraction, call):
    bad = truncate(logs[which], tmp_path / "truncated.h5", fraction)
    r = read_in_subprocess(call, bad)
    assert r.returncode == 3, (r.stdout, r.stderr)
    assert r.stdout.startswith("ancf.errors.ConfigError:") and "truncated" in r.stdout, r.stdout


@pytest.mark.parametrize("which", ["finished", "killed"])
def test_corrupt_log_is_a_typed_error_not_a_hang(logs, tmp_path, which):
    """2 KiB overwritten at several places: every read returns (the log, or a ConfigError) — a killed
    writer's log is read with SWMR, whose default metadata retries would block for hours."""
    data = logs[which].read_bytes()
    paths = []
    for k, frac in enumerate((0.3, 0.5, 0.7, 0.8, 0.9, 0.95)):
        bad = bytearray(data)
        at = int(len(bad) * frac)
        bad[at:at + 2048] = b"\xff" * 2048
        paths.append(tmp_path / f"corrupt{k}.h5")
        paths[-1].write_bytes(bytes(bad))
    code = textwrap.dedent(f"""
        from ancf.errors import ConfigError
        from hardware.runlog import summary
        from hardware.static_states import read_static_states
        for p in {[str(p) for p in paths]!r}:
            for call in (summary, read_static_states):
                try:
                    call(p)
                    print("OK")
                except ConfigError as exc:
                    print("ConfigError")
    """)
    try:
        r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                           capture_output=True, text=True, timeout=2 * TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail("reading a corrupt log hangs")
    assert r.returncode == 0, r.stderr[-2000:]                           # no untyped exception
    out = r.stdout.split()
    assert len(out) == 12 and set(out) <= {"OK", "ConfigError"} and "ConfigError" in out, out


def test_killed_writer_log_is_still_readable(logs):
    d = read_run_log(logs["killed"])
    assert d.rows == 40 and d.ended is None
    assert read_static_states(logs["killed"]).n_states == 2


@pytest.mark.parametrize("urgent", [False, True])
def test_a_crash_loses_at_most_the_last_unflushed_block(tmp_path, urgent):
    """Samples are written in blocks (flush_rows): a writer killed after 37 rows with blocks of 10 leaves 30 —
    unless a fault event came last, which is flushed at once with everything before it."""
    p = tmp_path / "blocks.h5"
    code = textwrap.dedent(f"""
        import os, signal
        from hardware.runlog import RunLog
        log = RunLog({str(p)!r}, n_tendons=3, flush_rows=10, flush_period=1e9)
        for k in range(37):
            log.sample(t=0.1 * k, iteration=k, tip=[0.17, 0.0, 0.001 * k], error_norm=1e-3 * k)
            log.event(0.1 * k, "converged", "a note that waits for the next block")
        if {urgent}:
            log.event(3.7, "fault", "drive 2: following error")
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                   timeout=TIMEOUT_S, check=False)
    d = read_run_log(p)
    assert d.rows == (37 if urgent else 30) and d.ended is None
    np.testing.assert_allclose(d.samples["iteration"], np.arange(d.rows))
    assert len(d.events) == (38 if urgent else 29)              # the 30th row flushed before its note
    assert (d.events[-1][1] == "fault") == urgent


def test_cli_log_show_on_a_truncated_log_is_one_error_line(logs, tmp_path):
    bad = truncate(logs["killed"], tmp_path / "truncated.h5", 0.5)
    try:
        r = subprocess.run([sys.executable, "-m", "validation.commands.main", "log", "show", str(bad)], cwd=ROOT,
                           env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True,
                           timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail("bellows log show hangs on a truncated log")
    assert r.returncode == 2 and r.stderr.strip().startswith("error:") and len(r.stderr.strip().splitlines()) == 1
    assert "truncated" in r.stderr


# ------------------------------------------------------------------------------------------ missing parts
def _copy_without(src, dst, *, drop=(), attrs=None, empty_samples=False):
    """Copy a finished log, leaving out groups ``drop``, replacing root attributes ``attrs``, or with an
    empty ``/samples`` group."""
    with h5py.File(src, "r") as fi, h5py.File(dst, "w") as fo:
        for k, v in fi.attrs.items():
            fo.attrs[k] = v
        for k, v in (attrs or {}).items():
            fo.attrs[k] = v
        for name in fi:
            if name in drop:
                continue
            if name == "samples" and empty_samples:
                fo.create_group("samples")
                continue
            fi.copy(fi[name], fo, name=name)
    return dst


def test_missing_events_group_is_a_clear_error(logs, tmp_path):
    bad = _copy_without(logs["finished"], tmp_path / "x.h5", drop=("events",))
    with pytest.raises(ConfigError, match=r"/events"):
        read_run_log(bad)


def test_missing_samples_group_is_a_clear_error(logs, tmp_path):
    bad = _copy_without(logs["finished"], tmp_path / "x.h5", drop=("samples",))
    with pytest.raises(ConfigError, match=r"/samples"):
        read_run_log(bad)


def test_empty_samples_give_a_summary(logs, tmp_path):
    p = _copy_without(logs["finished"], tmp_path / "x.h5", empty_samples=True)
    d = read_run_log(p)
    assert d.rows == 0
    text = summary(p)
    assert "samples: 0" in text
    out = export_csv(p, tmp_path / "x.csv")
    assert out.read_text().splitlines()[0].startswith("t_s") or out.read_text().strip() == ""


@pytest.mark.parametrize("value", ["{not json", "[1, 2]", "42"])
@pytest.mark.parametrize("attr", ["run", "rig"])
def test_malformed_json_attribute_is_a_clear_error(logs, tmp_path, attr, value):
    bad = _copy_without(logs["finished"], tmp_path / "x.h5", attrs={attr: value})
    with pytest.raises(ConfigError, match=f"'{attr}'"):
        read_run_log(bad)


def test_a_fresh_log_with_no_rows_has_a_summary(tmp_path):
    p = tmp_path / "empty.h5"
    RunLog(p, n_tendons=3).close()
    assert "samples: 0" in summary(p)


# ------------------------------------------------------------------------------------------ torn rows
def test_resized_rows_are_nan_not_zero(tmp_path):
    """A row that was resized but never written (writer killed between resize and write) reads as NaN."""
    p = tmp_path / "torn.h5"
    log = RunLog(p, n_tendons=3)
    log.sample(t=0.0, iteration=0, tip=[0.17, 0.0, 0.0], error_norm=1e-3, tension=[1.0, 2.0, 3.0])
    log.flush()                                              # the block with the first row is written
    for ds in log.samples.values():                          # the next row: resized everywhere, written nowhere
        ds.resize(ds.shape[0] + 1, axis=0)
    log.f.flush()
    log.close()
    d = read_run_log(p)
    assert d.rows == 2
    for name, a in d.samples.items():
        assert np.all(np.isnan(a[1])), f"{name}: torn row reads {a[1]}"
        assert np.all(np.isfinite(d.samples["t"][0]))


@pytest.mark.parametrize("torn_at", ["tensions", "pressure", "tip_position", "time"])
def test_a_torn_static_state_keeps_the_finished_ones(tmp_path, torn_at):
    p = tmp_path / "torn.h5"
    log = RunLog(p, n_tendons=3)
    for k in range(3):
        log.static_state(time=k, tensions=[1.0, 2.0, 3.0], pressure=6e4, tip=[0.17, 0.0, 0.001 * k])
    log.flush()                                              # the three states are on disk
    # a fourth state torn at ``torn_at``: the datasets before it written, ``torn_at`` resized only
    order = ["tensions", "pressure", "tip_position", "tip_force", "time"]
    vals = {"tensions": [1.0, 2.0, 3.0], "pressure": 6e4, "tip_position": [0.17, 0.0, 0.004],
            "tip_force": [np.nan] * 3, "time": 3.0}
    for name in order[:order.index(torn_at)]:
        RunLog._append(log.static[name], vals[name])
    ds = log.static[torn_at]
    ds.resize(ds.shape[0] + 1, axis=0)
    log.f.flush()
    log.close()
    st = read_static_states(p)
    assert st.n_states == 3
    np.testing.assert_allclose(st.tip_position[:, 2], [0.0, 0.001, 0.002])
    assert st.meta.get("torn_rows") == [3], st.meta


@pytest.mark.parametrize("command", ["show", "export"])
def test_log_show_clears_a_killed_writers_flags_so_any_reader_opens_it(tmp_path, command):
    """A SIGKILLed SWMR writer leaves the superblock marked open for write: plain (non-SWMR) HDF5 readers
    refuse the file.  'bellows log show' (and 'log export') clears the flags (like h5clear -s) once the writer is gone; the
    checksum it rewrites is HDF5's own lookup3 (HDF5 verifies it on open) and the data are intact."""
    import h5py
    from hardware.h5status import lookup3, status_flags
    p = write_log(tmp_path / "killed.h5", rows=12, static=1, kill=True)
    assert status_flags(p) != 0
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(p, "r").close()
    csv = tmp_path / "killed.csv"
    args = ["log", "show", str(p)] if command == "show" else ["log", "export", str(p), "--csv", str(csv)]
    r = subprocess.run([sys.executable, "-m", "validation.commands.main", *args], cwd=ROOT,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert r.returncode == 0 and "cleared the file's open-for-write flags" in r.stderr
    if command == "export":
        assert len(csv.read_text().splitlines()) == 1 + 12                # header + the 12 rows written
    assert status_flags(p) == 0
    with h5py.File(p, "r") as f:                       # a plain reader now
        np.testing.assert_allclose(f["samples/iteration"][:], np.arange(12))
    assert lookup3(b"") == 0xDEADBEEF and lookup3(b"Four score and seven years ago") == 0x17770551   # reference values
    again = subprocess.run([sys.executable, "-m", "validation.commands.main", "log", "show", str(p)], cwd=ROOT,
                           env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True,
                           timeout=TIMEOUT_S)
    assert again.returncode == 0 and "cleared" not in again.stderr        # nothing left to do


def test_a_live_writers_flags_are_left_alone(tmp_path):
    from hardware.h5status import status_flags
    from hardware.runlog import recover_crashed_log
    log = RunLog(tmp_path / "live.h5", n_tendons=3)             # this process writes it
    log.sample(t=0.0, iteration=0)
    log.flush()
    assert status_flags(log.path) != 0
    assert recover_crashed_log(log.path) is None and status_flags(log.path) != 0
    log.close()
    assert status_flags(log.path) == 0
