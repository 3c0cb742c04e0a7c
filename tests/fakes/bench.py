"""A whole fake bench whose tip follows the model: three fake EPOS4 drives (CiA 402 on python-can's virtual
bus), a load-cell board and a valve controller on pseudo-terminals, and a NatNet stream over loopback UDP;
a physics thread reads the drives' positions and the chamber pressure and sets the tracked tip and the
tendon tensions to the locked-length equilibrium the ``ancf`` model predicts (no load on the tip).

    with ModelBench(presets.paper(), counts_per_mm=2000, initial_lengths=l0) as bench:
        bench.rig_file(doc_toml_text, path)     # the doc's rig file, its devices pointing at the fakes
        ...                                     # run 'bellows control --rig path ...'
"""

from __future__ import annotations

import socket
import threading
import time
import uuid

import numpy as np

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # Python 3.10 (tomli is a base dependency there)
    import tomli as tomllib

from hardware.tracking import build_frame_packet

from .cia402_drive import FakeEpos4
from .serial_instruments import FakeSerialInstrument


class FakeNatNet:
    """Streams one rigid body at 100 Hz to a UDP port on 127.0.0.1 (``position`` in tracker coordinates [m])."""

    def __init__(self, port: int, body_id: int = 1):
        self.port, self.body_id = port, body_id
        self.position, self.tracked = (0.0, 0.0, 0.0), True
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._t.start()

    def _run(self):
        tx, k = socket.socket(socket.AF_INET, socket.SOCK_DGRAM), 0
        while not self._stop.is_set():
            tx.sendto(build_frame_packet(k, bodies=[(self.body_id, tuple(self.position), (0, 0, 0, 1), 1e-4,
                                                     self.tracked)]), ("127.0.0.1", self.port))
            k += 1
            time.sleep(0.01)
        tx.close()

    def stop(self):
        self._stop.set()
        self._t.join(timeout=1)


def free_udp_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def dump_toml(data: dict) -> str:
    """A small TOML writer for rig files: top-level keys, tables and arrays of tables of plain values."""
    out = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)
           and not (isinstance(v, list) and v and isinstance(v[0], dict))]
    for k, v in data.items():
        if isinstance(v, dict):
            out += ["", f"[{k}]"] + [f"{kk} = {_toml_value(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                out += ["", f"[[{k}]]"] + [f"{kk} = {_toml_value(vv)}" for kk, vv in item.items()]
    return "\n".join(out) + "\n"


class ModelBench:
    """The fake devices of a 3-tendon bench plus a physics thread (see the module docstring).

    params : the actuator the fake bench *is* (``ancf`` parameters);  counts_per_mm, zero_length_mm : the
    drives' encoder scale, as in the rig file;  initial_lengths (3,) [m] : where the drives start;
    force_scale_N_per_count : the load-cell board's scale, as in the rig file;  rotation, offset_mm : the
    tracker calibration of the rig file (p_actuator = R · p_tracker + offset).
    """

    def __init__(self, params, *, counts_per_mm: float, initial_lengths, zero_length_mm: float = 0.0,
                 force_scale_N_per_count: float = 0.001, rotation=None, offset_mm=(0.0, 0.0, 0.0)):
        from ancf import Model
        self.model = Model(params)
        self.cpm, self.zero = counts_per_mm * 1e3, zero_length_mm * 1e-3          # counts per metre, m
        self.scale = force_scale_N_per_count
        self.R = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.offset = np.asarray(offset_mm, float) * 1e-3
        self.channel = f"bench-{uuid.uuid4().hex[:8]}"
        l0 = np.asarray(initial_lengths, float)
        self.n = len(l0)
        self.drives = [FakeEpos4(node_id=i + 1, channel=self.channel,
                                 initial_counts=int(round((l0[i] - self.zero) * self.cpm))) for i in range(len(l0))]
        self.loadcells = FakeSerialInstrument()
        self.valves = FakeSerialInstrument()
        self.port = free_udp_port()
        self.natnet = FakeNatNet(self.port)
        self.updates = 0
        self.errors: list = []
        self._eq = None
        self._stop = threading.Event()

    # ---------------------------------------------------------------------------------- physics
    def lengths(self) -> np.ndarray:
        return np.array([d.pos for d in self.drives]) / self.cpm + self.zero

    def update(self, pressure: float) -> None:
        """Set the tracked tip and the tensions to the model's locked equilibrium for the drives now."""
        prev = self._eq
        eq = self.model.fk_locked(self.lengths(), pressure, (0.0, 0.0, 0.0), q0=None if prev is None else prev.q,
                                  tensions0=None if prev is None else prev.tensions)
        self._eq = eq
        self.natnet.position = tuple(self.R.T @ (eq.tip - self.offset))
        self.loadcells.forces = [int(round(max(T, 0.0) / self.scale)) for T in eq.tensions]
        self.updates += 1

    def _physics(self):
        while not self._stop.is_set():
            p = self.valves.pressure
            if p > 0:                                   # before the supply is set the tip keeps its last pose
                try:
                    self.update(p)
                except Exception as exc:               # noqa: BLE001 - report, keep the last pose
                    self.errors.append(f"{type(exc).__name__}: {exc}")
            time.sleep(0.01)

    # ---------------------------------------------------------------------------------- lifecycle
    def __enter__(self):
        self.loadcells.__enter__()
        self.valves.__enter__()
        for d in self.drives:
            d.__enter__()
        self._thread = threading.Thread(target=self._physics, daemon=True)
        return self

    def start(self, pressure: float) -> None:
        """Compute the first equilibrium at ``pressure`` [Pa] (compiles the model's kernels), then stream."""
        self.update(pressure)
        self.natnet.start()
        self._thread.start()

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self.natnet.stop() if self.natnet._t.is_alive() else None
        for d in self.drives:
            d.__exit__(None, None, None)
        self.valves.__exit__(None, None, None)
        self.loadcells.__exit__(None, None, None)
        return False

    # ---------------------------------------------------------------------------------- rig file
    def rig_file(self, toml_text: str) -> str:
        """The rig file ``toml_text`` (e.g. the documented example) with one drive and one force sensor per
        tendon and every device pointing at these fakes; everything else (limits, scales, calibration,
        speeds) as written.  Returns the TOML text."""
        data = tomllib.loads(toml_text)
        d0, f0 = data["drives"][0], data["force_sensors"][0]
        data["drives"] = [{**d0, "node_id": i + 1, "interface": "virtual", "channel": self.channel}
                          for i in range(self.n)]
        data["force_sensors"] = [{**f0, "port": self.loadcells.port, "channel": i + 1} for i in range(self.n)]
        data["pressure"] = {**data["pressure"], "port": self.valves.port}
        data["tracker"] = {**data["tracker"], "address": "127.0.0.1", "port": self.port}
        data["tracker"].pop("multicast_group", None)
        return dump_toml(data)


class ProcessModelBench(ModelBench):
    """The same bench with its drives in another process (:class:`fakes.drive_process.DriveProcess`, their own
    SYNC clock, reached over :mod:`fakes.canbridge`), run in cyclic synchronous position: a host stall cannot
    stall them, and they record every per-SYNC demand step.  ``.proc`` is the drive process; the rig file's
    drives are written ``cyclic = true`` at ``sync_period_ms``."""

    def __init__(self, params, *, counts_per_mm: float, initial_lengths, sync_period_ms: float = 5.0,
                 max_mm_per_s: float = 1000.0, **kw):
        super().__init__(params, counts_per_mm=counts_per_mm, initial_lengths=initial_lengths, **kw)
        from .canbridge import register
        from .drive_process import DriveProcess
        self.interface = register()
        self.sync_period_ms = float(sync_period_ms)
        l0 = np.asarray(initial_lengths, float)
        counts = [int(round((li - self.zero) * self.cpm)) for li in l0]
        self.proc = DriveProcess([{"node_id": i + 1, "initial_counts": c, "target_counts": c,
                                   "max_counts_per_s": max_mm_per_s * 1e-3 * self.cpm} for i, c in enumerate(counts)])
        self.nodes = [i + 1 for i in range(len(counts))]
        self.drives = []                               # no in-process drives

    def lengths(self) -> np.ndarray:
        pos = self.proc.positions()
        return np.array([pos[n] for n in self.nodes], float) / self.cpm + self.zero

    def __enter__(self):
        self.proc.__enter__()
        try:
            return super().__enter__()
        except BaseException:
            self.proc.__exit__(None, None, None)
            raise

    def __exit__(self, *exc):
        try:
            return super().__exit__(*exc)
        finally:
            self.proc.__exit__(None, None, None)

    def rig_file(self, toml_text: str) -> str:
        data = tomllib.loads(super().rig_file(toml_text))
        data["drives"] = [{**d, "interface": self.interface, "channel": self.proc.channel, "cyclic": True,
                           "sync_period_ms": self.sync_period_ms} for d in data["drives"]]
        return dump_toml(data)
