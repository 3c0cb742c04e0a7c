"""The five top-level packages import as real packages (not shadowed by same-named test folders)."""

import importlib
import pathlib

import pytest

ROOT = pathlib.Path(__file__).parents[1]


@pytest.mark.parametrize("name", ["ancf", "fem_reference", "validation", "controller", "hardware"])
def test_package_is_the_projects(name):
    mod = importlib.import_module(name)
    assert mod.__file__ is not None, f"{name} resolved to a namespace package (a tests/{name} folder?)"
    assert pathlib.Path(mod.__file__).resolve().parent == (ROOT / name).resolve()


def test_no_test_folder_shadows_a_package():
    for name in ("ancf", "fem_reference", "validation", "controller", "hardware"):
        assert not (ROOT / "tests" / name).exists(), f"tests/{name} would shadow the package under pytest"
