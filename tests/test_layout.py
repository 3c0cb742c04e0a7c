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
           "fem_reference": {"ancf"},        # only fem_reference/errors.py, guarded (checked below)
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


def _ancf_imports(path: pathlib.Path) -> list[tuple[int, bool]]:
    """Every import of ``ancf`` (or a module of it) in a file: (line, guarded), guarded meaning inside a
    ``try`` that handles ``ModuleNotFoundError`` (the FEM then runs without ancf)."""
    import ast
    tree = ast.parse(path.read_text())
    guarded = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Try) and any("ModuleNotFoundError" in ast.unparse(h.type or ast.Name("BaseException"))
                                             for h in node.handlers):
            guarded |= {id(n) for part in (node.body, node.orelse) for stmt in part for n in ast.walk(stmt)}
    found = []
    for node in ast.walk(tree):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                 [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
        if any(n == "ancf" or n.startswith("ancf.") for n in names):
            found.append((node.lineno, id(node) in guarded))
    return found


def test_only_fem_reference_errors_imports_ancf_and_only_guarded():
    """The FEM stays an independent reference: no module of it imports ``ancf`` but fem_reference/errors.py,
    whose import is guarded (without ancf the FEM takes its standalone error tree)."""
    found = {str(p.relative_to(ROOT)): _ancf_imports(p) for p in sorted((ROOT / "fem_reference").rglob("*.py"))}
    assert {k: v for k, v in found.items() if v and k != "fem_reference/errors.py"} == {}
    assert found["fem_reference/errors.py"] and all(g for _, g in found["fem_reference/errors.py"])


def test_the_ancf_import_scan_sees_imports_and_guards(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("import numpy\nfrom ancf.textfmt import vector\nimport ancf.errors as e\nfrom .errors import X\n"
                 "try:\n    import ancf\nexcept ModuleNotFoundError:\n    pass\nelse:\n    from ancf import errors\n"
                 "try:\n    import ancf\nexcept ValueError:\n    pass\n")
    assert sorted(_ancf_imports(f)) == [(2, False), (3, False), (6, True), (10, True), (12, False)]


# run with ``import ancf`` refused (sys.modules["ancf"] = None: ModuleNotFoundError, as if not installed)
_WITHOUT_ANCF = """
import importlib, json, pickle, pkgutil, sys
sys.modules["ancf"] = None
import fem_reference
mods = [m.name for m in pkgutil.walk_packages(fem_reference.__path__, "fem_reference.")]
for name in mods:
    importlib.import_module(name)
from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel, errors
model = BellowsModel(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2),
                     Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))
tip = model.solve(tensions=(0.5, 0.0, 0.0)).tip_position.tolist()
try:
    Material.neo_hookean("0.8", 40e6)
    raised = None
except errors.BellowsError as exc:
    raised = [c.__module__ + "." + c.__name__ for c in type(exc).__mro__]
conv = pickle.loads(pickle.dumps(errors.ConvergenceError("no", solver="fem", iterations=3, residual_norm=1.0,
                                                         tolerance=1e-8, history=[2.0, 1.0])))
print(json.dumps({"modules": mods, "standalone": errors.STANDALONE, "tip": tip, "raised": raised,
                  "conv": [conv.solver, conv.iterations, conv.history],
                  "ancf": sorted(m for m in sys.modules if m.split(".")[0] == "ancf" and sys.modules[m] is not None)}))
"""


def test_fem_reference_imports_solves_and_raises_without_ancf():
    """Every module of fem_reference imports with ``ancf`` absent; a tiny tube solves to the same tip as in the
    full install, and a bad value raises the standalone tree's ConfigError (a ValueError)."""
    import json
    import subprocess
    import sys

    import numpy as np

    from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel
    out = subprocess.run([sys.executable, "-c", _WITHOUT_ANCF], capture_output=True, text=True, timeout=600,
                         cwd=ROOT)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["standalone"] is True and got["ancf"] == []
    assert {"fem_reference.model", "fem_reference.render", "fem_reference.loads.caps"} <= set(got["modules"])
    assert got["raised"][:2] == ["fem_reference._standalone_errors.ConfigError",
                                 "fem_reference._standalone_errors.BellowsError"] and "builtins.ValueError" in got["raised"]
    assert got["conv"] == ["fem", 3, [2.0, 1.0]]
    model = BellowsModel(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2),
                         Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))
    tip = model.solve(tensions=(0.5, 0.0, 0.0)).tip_position
    assert np.allclose(got["tip"], tip, rtol=0, atol=1e-12) and tip[2] > 1e-5      # bent toward the pulled tendon


def test_fem_reference_errors_are_the_products_errors():
    """With ancf installed there is one tree: the FEM's error classes are ancf.errors' own."""
    import ancf.errors
    import fem_reference.errors as fe
    from fem_reference import Material
    assert fe.STANDALONE is False
    for name in ("BellowsError", "ConfigError", "InputError", "LimitError", "ConvergenceError",
                 "UnstableEquilibriumError", "check_finite"):
        assert getattr(fe, name) is getattr(ancf.errors, name), name
    with pytest.raises(ancf.errors.ConfigError):
        Material.neo_hookean("0.8", 40e6)


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


def _sibling_imports(path: pathlib.Path, siblings: set[str]) -> set[str]:
    """Modules of the same package a module imports, relative (``from .x import``, ``from . import x``) or
    absolute (``from hardware.x import``, ``import hardware.x``), at module level or inside functions."""
    import ast
    pkg, found = path.parent.name, set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            found |= {node.module.split(".")[0]} if node.module else {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            parts = node.module.split(".")
            if parts[0] == pkg:
                found |= {parts[1]} if len(parts) > 1 else {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[1] for a in node.names
                      if a.name.split(".")[0] == pkg and "." in a.name}
    return (found & siblings) - {path.stem}


def _find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import cycle of ``graph`` (module → modules it imports) as [a, b, …, a], or [] if there is none."""
    state: dict[str, int] = {}          # 1: on the current path, 2: done
    path: list[str] = []

    def visit(u):
        state[u] = 1
        path.append(u)
        for v in sorted(graph.get(u, ())):
            if state.get(v) == 1:
                return path[path.index(v):] + [v]
            if v not in state and (cycle := visit(v)):
                return cycle
        state[u] = 2
        path.pop()
        return []

    for u in sorted(graph):
        if u not in state and (cycle := visit(u)):
            return cycle
    return []


def test_find_cycle_finds_cycles_and_only_cycles():
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": set(), "d": {"a", "c"}}) == []
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _find_cycle({"x": {"y"}, "y": {"z"}, "z": {"y"}}) == ["y", "z", "y"]


@pytest.mark.parametrize("package", ["hardware", "controller"])
def test_modules_of_a_package_import_each_other_in_no_cycle(package):
    """Within a package the modules form a DAG (imports inside functions counted too): e.g. hardware.config ↔
    hardware.rig through build_rig would be a cycle."""
    files = {p.stem: p for p in (ROOT / package).glob("*.py") if p.stem != "__init__"}
    graph = {name: _sibling_imports(p, set(files)) for name, p in files.items()}
    assert sum(map(len, graph.values())) >= len(graph) // 2, "the import scan found (almost) no imports"
    assert _find_cycle(graph) == [], f"{package} modules import each other in a cycle"


# inside validation/: subpackages named by their jobs, each importing only the ones before it in this order
VALIDATION_LAYERS = ("infra", "reference", "identification", "checks", "report", "paper", "commands")


def _validation_imports(path: pathlib.Path, root: pathlib.Path = ROOT) -> set[str]:
    """Dotted ``validation.…`` modules a module imports (absolute or relative, module level or in functions);
    ``from validation.x import y`` counts as ``validation.x.y`` (y may be a module)."""
    import ast
    here = ["validation", *path.relative_to(root / "validation").parent.parts]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = here[:len(here) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            if mod == "validation" or mod.startswith("validation."):
                found |= {f"{mod}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("validation.")}
    return found


def _layer_violations(layer: str, root: pathlib.Path = ROOT) -> dict:
    """{file: [layers it imports against the order]} of validation/<layer>/."""
    allowed = set(VALIDATION_LAYERS[:VALIDATION_LAYERS.index(layer) + 1])
    bad = {}
    for p in sorted((root / "validation" / layer).rglob("*.py")):
        used = {m.split(".")[1] for m in _validation_imports(p, root)}
        if used - allowed:
            bad[str(p.relative_to(root))] = sorted(used - allowed)
    return bad


def _layer_cycle(layer: str, root: pathlib.Path = ROOT) -> list:
    files = {p.stem: p for p in (root / "validation" / layer).glob("*.py") if p.stem != "__init__"}
    prefix = f"validation.{layer}."
    graph = {name: {m[len(prefix):].split(".")[0] for m in _validation_imports(p, root) if m.startswith(prefix)}
             & (set(files) - {name}) for name, p in files.items()}
    return _find_cycle(graph)


def test_validation_has_only_its_named_subpackages():
    """No module sits loose in validation/ beside the subpackages (its __init__ is the public API)."""
    loose = sorted(p.name for p in (ROOT / "validation").glob("*.py") if p.name != "__init__.py")
    assert loose == [], f"modules outside the subpackages: {loose}"
    subs = {p.name for p in (ROOT / "validation").iterdir() if (p / "__init__.py").exists()}
    assert subs == set(VALIDATION_LAYERS)


@pytest.mark.parametrize("layer", VALIDATION_LAYERS)
def test_validation_subpackages_import_only_the_layers_before_them(layer):
    assert _layer_violations(layer) == {}, f"imports against the order {' < '.join(VALIDATION_LAYERS)}"


@pytest.mark.parametrize("layer", VALIDATION_LAYERS)
def test_modules_of_a_validation_subpackage_import_each_other_in_no_cycle(layer):
    assert _layer_cycle(layer) == [], f"validation.{layer} modules import each other in a cycle"


def test_the_validation_scans_catch_upward_imports_and_cycles(tmp_path):
    """The scans are not blind: relative and absolute, module-level and in-function imports are all seen."""
    ident = tmp_path / "validation" / "identification"
    ident.mkdir(parents=True)
    (ident / "a.py").write_text("def f():\n    from validation.checks.compare import validate\n")
    (ident / "b.py").write_text("from ..report import figures\nfrom . import c\n")
    (ident / "c.py").write_text("import validation.identification.b\n")
    assert _layer_violations("identification", tmp_path) == {
        "validation/identification/a.py": ["checks"], "validation/identification/b.py": ["report"]}
    assert _layer_cycle("identification", tmp_path) in (["b", "c", "b"], ["c", "b", "c"])
    assert _validation_imports(ROOT / "validation" / "commands" / "main.py") >= {
        "validation.commands.control", "validation.commands.identify", "validation.commands.paper.app"}


# no function hides its steps: at most this many lines, outside generated code and compiled (numba) kernels
MAX_FUNCTION_LINES = 120
_SCANNED = ("ancf", "fem_reference", "validation", "controller", "hardware", "benchmarks", "examples", "tests")


def _is_compiled_kernel(node) -> bool:
    """Decorated with numba's ``njit``/``jit``/``vectorize`` (a kernel: one loop nest the compiler sees whole)."""
    import ast
    for d in node.decorator_list:
        f = d.func if isinstance(d, ast.Call) else d
        name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
        if name in ("njit", "jit", "vectorize", "guvectorize", "cfunc"):
            return True
    return False


def _long_functions(paths, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, str, int]]:
    import ast
    out = []
    for p in paths:
        if "generated" in p.name:
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_compiled_kernel(node):
                n = node.end_lineno - node.lineno + 1
                if n > limit:
                    out.append((str(p.relative_to(ROOT) if p.is_relative_to(ROOT) else p), node.name, n))
    return out


def test_no_function_is_longer_than_the_limit():
    paths = [p for d in _SCANNED for p in sorted((ROOT / d).rglob("*.py"))]
    assert len(paths) > 100
    assert _long_functions(paths) == [], f"functions over {MAX_FUNCTION_LINES} lines: split them into named steps"


def test_the_length_scan_sees_long_functions_and_exempts_only_kernels(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    (tmp_path / "m.py").write_text(f"def long():\n{body}\n\n@njit(cache=True)\ndef kernel():\n{body}\n\n"
                                   f"class A:\n    def method(self):\n    {body.replace(chr(10) + '    ', chr(10) + '        ')}")
    assert sorted((f, n) for _, f, n in _long_functions([tmp_path / "m.py"])) == [
        ("long", MAX_FUNCTION_LINES + 1), ("method", MAX_FUNCTION_LINES + 1)]
