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
from hardware.errors import RigConfigError

ROOT = pathlib.Path(__file__).resolve().parents[2]


def documented_rig() -> dict:
    text = (ROOT / "docs/rig.md").read_text()
    section = text[text.index("## Rig files (TOML)"):]
    return tomllib.loads(re.search(r"```toml\n(.*?)```", section, flags=re.S).group(1))


def load(tmp_path, data: dict) -> RigConfig:
    path = tmp_path / "rig.toml"
    path.write_text(dump_toml(data))
    return RigConfig.from_toml(path)


def _set(path: str, value):
    def edit(d):
        *head, last = path.split(".")
        node = d
        for h in head:
            node = node[int(h)] if h.isdigit() else node[h]
        node[int(last) if last.isdigit() else last] = value
    return edit


def _both(*edits):
    def edit(d):
        for e in edits:
            e(d)
    return edit


def _rename(path: str, old: str, new: str):
    def edit(d):
        node = d
        for h in path.split("."):
            node = node[int(h)] if h.isdigit() else node[h]
        node[new] = node.pop(old)
    return edit


def _extra_tendon(d):
    d["drives"].append({**d["drives"][0], "node_id": 4})
    d["force_sensors"].append({**d["force_sensors"][0], "port": "/dev/ttyACM2", "channel": 1})


def _one_tendon_less(d):
    d["drives"].pop()
    d["force_sensors"].pop()


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
    _both(*[_set(f"drives.{i}.counts_per_mm", c) for i, c in enumerate((10, 1e6, 2000))]),      # range ends
    _set("tracker.port", 65535),
    _set("tracker.natnet_version", "4.1"),
], ids=["node id on another bus", "channel on another board", "counts at the range ends", "tracker port 65535",
        "NatNet 4.1"])
def test_plausible_variants_load(tmp_path, edit):
    data = copy.deepcopy(documented_rig())
    edit(data)
    load(tmp_path, data)


def test_cli_refuses_a_conflicting_rig_file_with_one_error_line(tmp_path, monkeypatch, capsys):
    from validation.cli import main
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
