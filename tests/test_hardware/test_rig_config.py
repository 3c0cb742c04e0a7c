"""Rig files are checked for conflicts at load time, before any hardware is touched: each variant of the
documented example rig file (docs/rig.md, "Rig files (TOML)") below is a ``RigConfigError`` naming the keys.

The variants are made by editing the parsed example and writing it back as TOML (the file the user would
write), so every test starts from the documented file.
"""

import copy
import pathlib
import re

import pytest

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

from fakes.bench import dump_toml
from hardware import RigConfig
from hardware.errors import LimitError, RigConfigError

ROOT = pathlib.Path(__file__).resolve().parents[2]


def documented_rig() -> dict:
    text = (ROOT / "docs/rig.md").read_text()
    section = text[text.index("## Rig files (TOML)"):]
    return tomllib.loads(re.search(r"```toml\n(.*?)```", section, flags=re.S).group(1))


def load(tmp_path, data: dict) -> RigConfig:
    path = tmp_path / "rig.toml"
    path.write_text(dump_toml(data))
    return RigConfig.from_toml(path)


def _node(d, path: str):
    """The table at ``path`` ("drives.1", "tracker"; "" is the top level)."""
    for h in path.split(".") if path else ():
        d = d[int(h)] if h.isdigit() else d[h]
    return d


def _set(path: str, value):
    def edit(d):
        head, _, last = path.rpartition(".")
        _node(d, head)[int(last) if last.isdigit() else last] = value
    return edit


def _both(*edits):
    def edit(d):
        for e in edits:
            e(d)
    return edit


def _rename(path: str, old: str, new: str):
    def edit(d):
        node = _node(d, path)
        node[new] = node.pop(old)
    return edit


def _extra_tendon(d):
    d["drives"].append({**d["drives"][0], "node_id": 4})
    d["force_sensors"].append({**d["force_sensors"][0], "port": "/dev/ttyACM2", "channel": 1})


def _one_tendon_less(d):
    d["drives"].pop()
    d["force_sensors"].pop()


def _cyclic(*drives, **keys):
    """``cyclic = true`` (and ``keys``) on the drives ``drives``."""
    def edit(d):
        for i in drives:
            d["drives"][i].update({"cyclic": True, **keys})
    return edit


def _pop(path: str, key: str):
    def edit(d):
        _node(d, path).pop(key)
    return edit


def _simulated_rig_with(*keep):
    """The documented file as a ``backend = "sim"`` rig, keeping only the device tables ``keep``."""
    def edit(d):
        d["backend"] = "sim"
        for k in ("drives", "force_sensors", "pressure", "tracker"):
            if k not in keep:
                d.pop(k)
    return edit


BAD = {
    "duplicate node id on one bus": (_set("drives.1.node_id", 1), ["drives[0].node_id", "drives[1].node_id", "can0"]),
    "node id 0": (_set("drives.2.node_id", 0), ["drives[2].node_id", "1…127"]),
    "node id 128": (_set("drives.2.node_id", 128), ["drives[2].node_id", "1…127"]),
    "bitrates differ on one bus": (_set("drives.1.bitrate", 500_000), ["drives[0].bitrate", "drives[1].bitrate"]),
    "not a CAN bitrate": (_both(*[_set(f"drives.{i}.bitrate", 123) for i in range(3)]), ["drives[0].bitrate"]),
    "two tendons on one sensor channel": (_set("force_sensors.2.channel", 1),
                                          ["force_sensors[0].channel", "force_sensors[2].channel", "/dev/ttyACM0"]),
    "sensor channel 0": (_set("force_sensors.0.channel", 0), ["force_sensors[0].channel", "1…3"]),
    "sensor channel 4": (_set("force_sensors.1.channel", 4), ["force_sensors[1].channel", "1…3"]),
    "baudrate 0": (_set("force_sensors.0.baudrate", 0), ["force_sensors[0].baudrate"]),
    "pressure on the load-cell port": (_set("pressure.port", "/dev/ttyACM0"), ["pressure.port", "force_sensors[0].port"]),
    "tracker port 0": (_set("tracker.port", 0), ["tracker.port", "1…65535"]),
    "tracker port 70000": (_set("tracker.port", 70000), ["tracker.port", "1…65535"]),
    "one drive less than tendons": (_one_tendon_less, ["drives", "3 tendons"]),
    "one drive more than tendons": (_extra_tendon, ["drives", "3 tendons"]),
    "zero counts": (_set("drives.1.counts_per_mm", 0), ["drives[1].counts_per_mm"]),
    "negative counts": (_set("drives.1.counts_per_mm", -2000), ["drives[1].counts_per_mm"]),
    "absurdly many counts": (_set("drives.0.counts_per_mm", 1e9), ["drives[0].counts_per_mm", "10…1e+06"]),
    "counts per metre written for per mm": (_rename("drives.2", "counts_per_mm", "counts_per_m"),
                                            ["drives[2].counts_per_m", "10…1e+06"]),
    "NatNet 2.x stream": (_set("tracker.natnet_version", "2.9"), ["tracker.natnet_version", "3.0 or later"]),
    "NatNet version not a number": (_set("tracker.natnet_version", "four"), ["tracker.natnet_version"]),
    "travel beyond the 32-bit position range": (_both(_set("drives.0.counts_per_mm", 1e6),
                                                      _set("drives.0.zero_length_mm", -3000)),
                                                ["drives[0].counts_per_mm", "drives[0].zero_length_mm", "32-bit"]),
    # --- settings that contradict each other (accepted before, except where a new key takes part) ----------
    "cyclic drives on one bus asking for two SYNC periods": (
        _both(_cyclic(0, sync_period_ms=2), _cyclic(1, sync_period_ms=5)),
        ["drives[0].sync_period_ms", "drives[1].sync_period_ms", "socketcan:can0", "one SYNC"]),
    "a SYNC period against another drive's default": (
        _both(_cyclic(0, 1), _cyclic(2, sync_period_s=0.005)),
        ["drives[0].sync_period_*", "drives[2].sync_period_s", "default 2 ms", "socketcan:can0"]),
    "sync_period on a profile-position drive": (_set("drives.0.sync_period_ms", 2),
                                                ["drives[0].sync_period_ms", "drives[0].cyclic"]),
    "heartbeat_timeout on a drive with cyclic = false": (
        _both(_set("drives.1.cyclic", False), _set("drives.1.heartbeat_timeout_ms", 500)),
        ["drives[1].heartbeat_timeout_ms", "drives[1].cyclic"]),
    "following_error_window on a profile-position drive": (_set("drives.2.following_error_window_mm", 1),
                                                           ["drives[2].following_error_window_mm", "drives[2].cyclic"]),
    "node 127 on a bus with a cyclic drive": (_both(_cyclic(0), _set("drives.2.node_id", 127)),
                                              ["drives[2].node_id", "127", "0x77F", "socketcan:can0"]),
    "a cyclic drive as node 127": (_both(_cyclic(0, 1, 2), _set("drives.1.node_id", 127)),
                                   ["drives[1].node_id", "0x77F"]),
    "[simulation] in a hardware rig file": (_set("simulation", {"seed": 3, "tracker_noise_mm": 0.05}),
                                            ["simulation.seed", "backend", "hardware"]),
    "a serial pressure supply in a simulated rig": (_simulated_rig_with("pressure"),
                                                    ["pressure.backend", "serial", "sim"]),
    "a NatNet tracker in a simulated rig": (_simulated_rig_with("tracker"), ["tracker.backend", "natnet", "sim"]),
    "heartbeat_timeout equal to the drive's heartbeat": (_cyclic(0, 1, 2, heartbeat_timeout_ms=50),
                                                         ["drives[0].heartbeat_timeout_ms", "50 ms"]),
    "heartbeat_timeout shorter than two host heartbeats": (_cyclic(0, 1, 2, heartbeat_timeout_ms=80),
                                                           ["drives[0].heartbeat_timeout_ms", "100"]),
    "heartbeat_timeout beyond the 16-bit consumer heartbeat": (_cyclic(0, 1, 2, heartbeat_timeout_s=70),
                                                               ["drives[0].heartbeat_timeout_s", "65535 ms"]),
    "sync_period below 0.1 ms": (_cyclic(0, 1, 2, sync_period_ms=0.05), ["drives[0].sync_period_ms", "0.1 … 100 ms"]),
    "sync_period above 100 ms": (_cyclic(0, 1, 2, sync_period_s=0.2), ["drives[0].sync_period_s", "0.1 … 100 ms"]),
    "sync_period the drive cannot say": (_cyclic(0, 1, 2, sync_period_ms=2.35), ["drives[0].sync_period_ms", "0x60C2"]),
    "SYNC traffic longer than the SYNC period": (
        _both(_cyclic(0, 1, 2, sync_period_ms=2), *[_set(f"drives.{i}.bitrate", 500_000) for i in range(3)]),
        ["drives[0].bitrate", "drives[0].sync_period_ms", "socketcan:can0", "3 cyclic drives"]),
    "tendon speed below one count per SYNC period": (        # 100 counts/s: 1.5 rpm, but 0.1 count per SYNC
        _both(_cyclic(0, sync_period_ms=1), _set("drives.0.counts_per_mm", 10), _set("speed_mm_per_s", 10)),
        ["speed_mm_per_s", "drives[0].counts_per_mm", "drives[0].sync_period_ms", "1 count"]),
    "tendon speed below the drive's 1 rpm": (_set("drives.1.counts_per_turn", 1e9),
                                             ["speed_mm_per_s", "drives[1].counts_per_turn", "1 rpm"]),
    "speed_max below 1 rpm when no speed is given": (_both(_pop("", "speed_mm_per_s"),
                                                           _set("drives.1.counts_per_turn", 5e9)),
                                                     ["limits.speed_max_mm_per_s", "drives[1].counts_per_turn"]),
    "acceleration below the drive's 1 rpm/s": (_set("acceleration_mm_per_s2", 0.001),
                                               ["acceleration_mm_per_s2", "drives[0].counts_per_turn", "rpm/s"]),
    "force sensors on one port at two baudrates": (_both(_set("force_sensors.0.baudrate", 115200),
                                                         _set("force_sensors.1.baudrate", 9600)),
                                                   ["force_sensors[0].baudrate", "force_sensors[1].baudrate",
                                                    "/dev/ttyACM0"]),
    # --- new keys ---------------------------------------------------------------------------------------------
    "counts_per_turn missing": (_pop("drives.1", "counts_per_turn"), ["drives[1].counts_per_turn", "rpm", "speed"]),
    "counts_per_turn zero": (_set("drives.0.counts_per_turn", 0), ["drives[0].counts_per_turn", "> 0"]),
    "counts_per_turn negative": (_set("drives.2.counts_per_turn", -4096), ["drives[2].counts_per_turn", "> 0"]),
    "counts_per_turn as text": (_set("drives.2.counts_per_turn", "4096"), ["drives[2].counts_per_turn", "a number"]),
    "counts_per_turn with a unit": (_rename("drives.0", "counts_per_turn", "counts_per_turn_mm"),
                                    ["counts_per_turn_mm", "unknown key"]),
    "following_error_window zero": (_cyclic(0, 1, 2, following_error_window_mm=0),
                                    ["drives[0].following_error_window_mm", "> 0"]),
    "following_error_window negative": (_cyclic(0, 1, 2, following_error_window_m=-0.001),
                                        ["drives[0].following_error_window_m", "> 0"]),
    "following_error_window below one count": (_cyclic(0, 1, 2, following_error_window_mm=1e-4),
                                               ["drives[0].following_error_window_mm", "drives[0].counts_per_mm",
                                                "one count"]),
    "following_error_window beyond 32 bits": (_cyclic(0, 1, 2, following_error_window_m=3000),
                                              ["drives[0].following_error_window_m", "drives[0].counts_per_mm",
                                               "0xFFFFFFFF"]),
    "following_error_window without a unit": (_cyclic(0, 1, 2, following_error_window=1),
                                              ["following_error_window", "following_error_window_mm"]),
    "acceleration zero": (_set("acceleration_mm_per_s2", 0), ["acceleration_mm_per_s2", "> 0"]),
    "acceleration negative": (_both(_pop("", "acceleration_mm_per_s2"), _set("acceleration_m_per_s2", -0.05)),
                              ["acceleration_m_per_s2", "> 0"]),
    "acceleration without a unit": (_rename("", "acceleration_mm_per_s2", "acceleration"),
                                    ["acceleration", "acceleration_mm_per_s2", "acceleration_m_per_s2"]),
    "acceleration given twice": (_set("acceleration_m_per_s2", 0.05), ["acceleration", "twice"]),
}


def test_the_documented_rig_file_loads(tmp_path):
    cfg = load(tmp_path, documented_rig())
    assert len(cfg.drives) == len(cfg.force_sensors) == cfg.actuator_params().n_tendons == 3


@pytest.mark.parametrize("case", list(BAD))
def test_rig_file_conflicts_are_config_errors_naming_the_keys(tmp_path, case):
    edit, names = BAD[case]
    data = copy.deepcopy(documented_rig())
    edit(data)
    with pytest.raises(RigConfigError) as info:
        load(tmp_path, data)
    msg = str(info.value)
    assert "\n" not in msg
    for name in names:
        assert name in msg, f"{case}: {name!r} not in {msg!r}"


@pytest.mark.parametrize("edit", [
    _both(_set("drives.1.node_id", 1), _set("drives.1.channel", "can1")),           # same id, another bus
    _both(_set("force_sensors.2.channel", 1), _set("force_sensors.2.port", "/dev/ttyACM2")),  # another board
    _both(*[_set(f"drives.{i}.counts_per_mm", c) for i, c in enumerate((10, 1e6, 2000))],      # range ends
          _set("drives.0.counts_per_turn", 64)),           # 10 counts/mm at 4096 counts/turn: 5 mm/s is 0.73 rpm
    _set("tracker.port", 65535),
    _set("tracker.natnet_version", "4.1"),
    _cyclic(0, 1, 2),                                                                # CSP, every default
    _cyclic(0, 1, 2, sync_period_ms=2, heartbeat_timeout_ms=100, following_error_window_mm=1),
    _both(_cyclic(0, 1, 2, heartbeat_timeout_ms=65535, following_error_window_mm=0.0005),   # 1 count
          _set("acceleration_mm_per_s2", 0.06)),                                     # ≈ 1.8 rpm/s
    _both(_cyclic(0, 1, 2, sync_period_ms=2.5), *[_set(f"drives.{i}.bitrate", 500_000) for i in range(3)]),
    _both(_cyclic(0, 1, 2, sync_period_ms=25.5)),
    _both(_cyclic(0, 1, 2, sync_period_s=0.1)),
    _both(_cyclic(0, sync_period_ms=0.5), _set("drives.0.channel", "can1"),          # one drive on its own bus
          _set("drives.1.sync_period_ms", 3), _set("drives.1.cyclic", True)),
    _both(_cyclic(0, sync_period_ms=5), _cyclic(1, 2), *[_set(f"drives.{i}.channel", "can1") for i in (1, 2)]),
    _set("drives.2.node_id", 127),                                                   # no cyclic drive on can0
    _both(_cyclic(0, 1), _set("drives.2.channel", "can1"), _set("drives.2.node_id", 127)),
    _set("simulation", {}),
    _both(_pop("", "acceleration_mm_per_s2"), _set("acceleration_m_per_s2", 0.05)),
    _pop("", "acceleration_mm_per_s2"),
    _both(*[_set(f"force_sensors.{i}.baudrate", 9600) for i in range(3)]),           # one port, one baudrate
    _simulated_rig_with(),
], ids=["node id on another bus", "channel on another board", "counts at the range ends", "tracker port 65535",
        "NatNet 4.1", "all cyclic, defaults", "all cyclic, every key", "cyclic at the key ranges' ends",
        "cyclic at 500 kbit/s, 2.5 ms", "SYNC 25.5 ms", "SYNC 100 ms", "SYNC 0.5 ms, one drive on its bus",
        "two buses, two SYNC periods", "node 127 on a profile-position bus", "node 127 on a bus without cyclic drives",
        "empty [simulation] table", "acceleration in m/s²", "no acceleration", "one baudrate on the sensor port",
        "the file as a simulated rig"])
def test_plausible_variants_load(tmp_path, edit):
    data = copy.deepcopy(documented_rig())
    edit(data)
    load(tmp_path, data)


def test_new_keys_parse_to_si_values(tmp_path):
    data = documented_rig()
    cfg = load(tmp_path, data)
    assert cfg.acceleration == pytest.approx(0.05)                          # acceleration_mm_per_s2 = 50
    assert [d["counts_per_turn"] for d in cfg.drives] == [4096.0] * 3
    assert all(isinstance(d["counts_per_turn"], float) for d in cfg.drives)
    assert all("following_error_window" not in d for d in cfg.drives)       # no default stored: the builder's
    assert cfg.to_dict()["acceleration"] == pytest.approx(0.05)
    data.pop("acceleration_mm_per_s2")
    data["acceleration_m_per_s2"] = 0.2
    for d, w in zip(data["drives"], ({"following_error_window_mm": 1.5}, {"following_error_window_m": 0.002},
                                     {"following_error_window_mm": 1})):
        d.update(cyclic=True, counts_per_turn=2048.5, **w)
    cfg = load(tmp_path, data)
    assert cfg.acceleration == pytest.approx(0.2)
    assert [d["following_error_window"] for d in cfg.drives] == pytest.approx([1.5e-3, 2e-3, 1e-3])
    assert cfg.drives[0]["counts_per_turn"] == 2048.5
    assert cfg._key("drives[1]", "following_error_window") == "drives[1].following_error_window_m"
    assert cfg._key("", "acceleration") == "acceleration_m_per_s2"
    data.pop("acceleration_m_per_s2")
    assert load(tmp_path, data).acceleration is None


def test_a_simulated_rig_takes_an_acceleration(tmp_path):
    assert load(tmp_path, {"backend": "sim", "acceleration_mm_per_s2": 20}).acceleration == pytest.approx(0.02)
    with pytest.raises(RigConfigError, match="acceleration_m_per_s2"):
        load(tmp_path, {"backend": "sim", "acceleration_m_per_s2": 0})


def test_the_checks_agree_with_the_drive_classes():
    """The constants the checks use are the product's: the host heartbeat node and period, the drive's producer
    heartbeat and default SYNC period, and every accepted SYNC period is one the drive's 0x60C2 can say."""
    import inspect
    from hardware import config
    canbus = pytest.importorskip("hardware.canbus")
    cyc = pytest.importorskip("hardware.epos4_cyclic")
    assert config.HOST_HEARTBEAT_NODE == canbus.MASTER_NODE_ID
    assert config.HOST_HEARTBEAT_PERIOD == canbus.MASTER_HEARTBEAT_PERIOD
    defaults = {k: v.default for k, v in inspect.signature(cyc.Epos4CyclicDrive).parameters.items()}
    assert config.DRIVE_HEARTBEAT_TIME == defaults["heartbeat_time"]
    assert config.SYNC_PERIOD_DEFAULT == defaults["sync_period"]
    for n in range(1, 1001):                                   # 0.1 ms … 100 ms in steps of 0.1 ms
        period = n * 1e-4
        if config.sync_period_problem(period) is None:
            cyc.interpolation_period(period)                   # raises LimitError when the drive cannot say it
        else:
            with pytest.raises(LimitError):
                cyc.interpolation_period(period)


def test_cli_refuses_a_conflicting_rig_file_with_one_error_line(tmp_path, monkeypatch, capsys):
    from validation.commands.main import main
    data = documented_rig()
    data["drives"][2]["node_id"] = 1
    path = tmp_path / "rig.toml"
    path.write_text(dump_toml(data))
    monkeypatch.setattr("sys.argv", ["bellows", "control", "--rig", str(path), "--target-mm", "178,0,-55",
                                     "--pressure-kpa", "60", "--max-iterations", "1"])
    with pytest.raises(SystemExit) as info:
        main()
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and err[-1].startswith("error:") and "drives[2].node_id" in err[-1]
