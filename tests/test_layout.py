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


# imports point one way, down: validation → controller → hardware → ancf, validation → fem_reference
ALLOWED = {"ancf": set(), "hardware": {"ancf"}, "controller": {"hardware", "ancf"},
           "fem_reference": {"ancf"},        # model-free utilities of ancf only (checked below)
           "validation": {"controller", "hardware", "ancf", "fem_reference"}}


def _imported_packages(path: pathlib.Path) -> set[str]:
    """Top-level project packages a module imports anywhere (module level or inside functions)."""
    import ast
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
    return found & set(ALLOWED)


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_point_down(package):
    bad = {str(p.relative_to(ROOT)): sorted(_imported_packages(p) - ALLOWED[package] - {package})
           for p in sorted((ROOT / package).rglob("*.py"))}
    assert not {k: v for k, v in bad.items() if v}, "imports against the layering"


def test_fem_reference_uses_no_ancf_model():
    """The FEM stays an independent reference: from ancf it takes the exception tree and the command-line and
    output helpers (none of which loads the model or numba: tests/test_fem/test_fem_limits.py), nothing else."""
    import ast
    allowed = {"ancf.errors", "ancf.clitools", "ancf.outputs", "ancf.textfmt"}
    for p in sorted((ROOT / "fem_reference").rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("ancf"):
                names = [f"ancf.{a.name}" for a in node.names] if node.module == "ancf" else [node.module]
                assert set(names) <= allowed, f"{p.relative_to(ROOT)} imports {names}"


def _relative_imports(path: pathlib.Path) -> set[str]:
    """Sibling modules a module imports with ``from .x import`` (module level or inside functions)."""
    import ast
    return {node.module.split(".")[0] for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module}


@pytest.mark.parametrize("module, forbidden", [
    ("config", {"rig", "simulated", "build", "epos4", "serial_devices"}),    # the rig file knows no rig classes
    ("rig", {"config", "build", "simulated"}),                                 # the rig knows no rig file
    ("simulated", {"config", "build"}),
])
def test_building_a_rig_is_one_module_the_others_do_not_need(module, forbidden):
    """hardware.build is the only module that knows both the rig file and the rig classes: no cycle."""
    assert not _relative_imports(ROOT / "hardware" / f"{module}.py") & forbidden
    assert {"config", "rig", "simulated"} <= _relative_imports(ROOT / "hardware" / "build.py")
