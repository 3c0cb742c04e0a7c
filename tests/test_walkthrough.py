"""docs/walkthrough.md's rig file is a valid rig file: its header (the only part the page writes out) with the
device tables of docs/rig.md's example loads as a :class:`hardware.config.RigConfig`, and it names the actuator
that step 7 writes.  (Its commands run in tests/test_docs_commands.py.)"""

import pathlib
import re

from ancf import presets
from fakes.doc_commands import documented_rig_file

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _walkthrough_rig_header() -> str:
    blocks = re.findall(r"```toml\n(.*?)```", (ROOT / "docs" / "walkthrough.md").read_text(), re.S)
    return next(b for b in blocks if 'backend = "hardware"' in b)


def test_the_walkthrough_rig_file_loads(tmp_path):
    from hardware.config import RigConfig
    header = _walkthrough_rig_header()
    devices = documented_rig_file()[documented_rig_file().index("[[drives]]"):]
    (tmp_path / "lab_fit").mkdir()
    (tmp_path / "lab_fit" / "actuator.toml").write_text(presets.paper().to_toml())
    cfg = RigConfig.from_toml_string(header + "\n" + devices, where="walkthrough", base_dir=str(tmp_path))
    assert cfg.actuator == "lab_fit/actuator.toml"
    assert cfg.actuator_params().n_tendons == len(cfg.drives) == 3
    assert "lab_fit/actuator.toml" in (ROOT / "docs" / "walkthrough.md").read_text().split("## 7.")[1]
