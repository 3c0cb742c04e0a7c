"""The Python conventions of the packages: a version from the installed distribution, ``bellows --version``, and
``import validation`` as the public API of the commands, imported lazily (PEP 562)."""

import importlib.metadata
import os
import pathlib
import subprocess
import sys

import pytest

import ancf
import validation

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _run(*code_or_args, module=None):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    cmd = [sys.executable, "-m", module, *code_or_args] if module else [sys.executable, "-c", *code_or_args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)


def test_version_is_the_installed_distributions():
    expected = importlib.metadata.version("bellows")
    assert ancf.__version__ == expected and validation.__version__ == expected
    assert "__version__" in dir(ancf) and "__version__" in dir(validation)


def test_bellows_version_prints_it_and_exits_0_and_no_arguments_still_shows_help():
    r = _run("--version", module="validation.commands.main")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"bellows {importlib.metadata.version('bellows')}"
    bare = _run(module="validation.commands.main")
    assert bare.returncode == 0 and bare.stdout.startswith("Usage: bellows")
    assert "Tendon-pneumatic bellows actuators" in bare.stdout and "report" in bare.stdout
    assert "--version" in bare.stdout


API = {  # public name → (module, attribute) it must be
    "identify_from_fem": ("validation.identification.identify", "from_fem"),
    "identify_from_measurements": ("validation.identification.identify", "from_measurements"),
    "IdentificationResult": ("validation.identification.identify", "IdentificationResult"),
    "validate": ("validation.checks.compare", "validate"),
    "stiffness_vs_tension": ("validation.checks.compare", "stiffness_vs_tension"),
    "ValidationResult": ("validation.checks.compare", "ValidationResult"),
    "build_report": ("validation.report.build", "build_report"),
    "write_report": ("validation.report.build", "write_report"),
    "run_report": ("validation.report.pipeline", "run_report"),
    "load_design": ("validation.reference.designs", "load_design"),
}


def test_every_public_name_resolves_and_is_listed():
    import importlib
    assert set(API) <= set(validation.__all__)
    for name in validation.__all__:
        assert getattr(validation, name) is not None, name
        assert name in dir(validation)
    for name, (module, attr) in API.items():
        assert getattr(validation, name) is getattr(importlib.import_module(module), attr), name
    with pytest.raises(AttributeError, match="no_such_name"):
        validation.no_such_name        # noqa: B018


def test_import_validation_imports_no_subpackage_until_a_name_is_used():
    code = ("import sys, validation; print(sorted(m for m in sys.modules if m.startswith('validation.'))); "
            "validation.identify_from_measurements; "
            "print('validation.identification.identify' in sys.modules, 'validation.report' in sys.modules)")
    r = _run(code)
    assert r.returncode == 0, r.stderr
    before, after = r.stdout.strip().splitlines()
    assert before == "[]"
    assert after == "True False"          # only what the used name needs


def _readme_api_example() -> str:
    import re
    text = (ROOT / "README.md").read_text().split("## Python API", 1)[1]
    return re.search(r"```python\n(.*?)```", text, re.S).group(1)


def test_the_readme_example_uses_the_api_as_it_is(capsys):
    """README.md "Python API": every ``validation.x`` it names is public and every call binds to the function's
    signature (the FEM calls take minutes and are not run); its model lines run and print the one-line repr."""
    import ast
    import inspect
    code = _readme_api_example()
    tree = ast.parse(code)
    used = {n.attr for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == "validation"}
    assert used >= {"run_report", "identify_from_fem", "validate", "write_report", "identify_from_measurements",
                    "load_design"}
    assert used <= set(validation.__all__)
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
             and isinstance(n.func.value, ast.Name) and n.func.value.id == "validation"]
    for c in calls:
        inspect.signature(getattr(validation, c.func.attr)).bind(*c.args, **{k.arg: None for k in c.keywords})
    model_part = code.split("# `bellows report")[0]
    exec(compile(model_part, "README.md", "exec"), {})
    assert capsys.readouterr().out.startswith("Equilibrium(tip=(")
