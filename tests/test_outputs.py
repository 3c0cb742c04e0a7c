"""Output paths are checked before any work: writable, suffix, and no silent overwrite."""

import os

import pytest

from ancf.errors import InputError, OutputExistsError
from ancf.outputs import atomic_write_text, prepare_output_dir, prepare_output_file


def test_file_rules(tmp_path):
    p = prepare_output_file(tmp_path / "sub" / "run.h5", suffixes=(".h5",))
    assert p.parent.is_dir()
    with pytest.raises(InputError, match="must end in"):
        prepare_output_file(tmp_path / "run.txt", suffixes=(".h5",))
    p.write_text("x")
    with pytest.raises(OutputExistsError, match="--force"):
        prepare_output_file(p)
    assert prepare_output_file(p, force=True) == p
    with pytest.raises(InputError, match="folder"):
        prepare_output_file(tmp_path)


def test_dir_rules(tmp_path):
    d = prepare_output_dir(tmp_path / "out", ["a.json"])
    (d / "a.json").write_text("{}")
    with pytest.raises(OutputExistsError, match="a.json"):
        prepare_output_dir(d, ["a.json", "b.png"])
    prepare_output_dir(d, ["b.png"])
    prepare_output_dir(d, ["a.json"], force=True)
    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match="not a folder"):
        prepare_output_dir(tmp_path / "f")


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_folder(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    with pytest.raises(InputError, match="not writable"):
        prepare_output_dir(d)


def test_unwritable_folder_via_file_parent(tmp_path):
    (tmp_path / "blocker").write_text("")
    with pytest.raises(InputError, match="cannot create"):
        prepare_output_file(tmp_path / "blocker" / "x.json")


def test_atomic_write(tmp_path):
    p = atomic_write_text(tmp_path / "a.txt", "hello")
    assert p.read_text() == "hello" and not list(tmp_path.glob(".a.txt.tmp*"))
