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
