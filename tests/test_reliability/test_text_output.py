"""Numbers in text output and figure titles carry their unit and never show a numpy or list repr
(``[ 1.717e+02 1.860e-11 -3.112e+01]``, ``T = [2. 0. 0.] N``, ``np.float64(…)``, ``array(…)``)."""

import io
import re
from types import SimpleNamespace

import numpy as np
import pytest

from ancf import Model, presets
from ancf.textfmt import number, one_of, vector
from validation.commands.main import main

#: a numpy/list repr of numbers: "[ 1.7", "[2.", "[-0.3", "np.float64(", "array("
REPR = re.compile(r"\[\s*[-+]?(\d|\.\d)|np\.float\d*\(|array\(")


def assert_no_repr(text: str) -> None:
    m = REPR.search(text)
    assert m is None, f"array repr {m.group(0)!r} in: {text[max(0, m.start() - 60):m.end() + 60]!r}"


def test_the_pattern_catches_array_reprs():
    for bad in (str(np.array([171.7, 1.86e-11, -31.1])), f"T = {np.round(np.array([2.0, 0, 0]), 3)} N",
                repr(np.float64(1.5)), repr(np.array([1.0])), str([150.0, 0.0])):
        with pytest.raises(AssertionError):
            assert_no_repr(bad)
    assert_no_repr("tip x,y,z [mm]  T [N]  p [kPa]  (171.7, 0.0, -31.1) mm")


def test_helpers():
    assert vector(np.array([0.1717, 1.86e-14, -0.0311]), "mm", 1e3) == "(171.7, 0.0, -31.1) mm"
    assert vector([2.0, 0, 0], "N") == "(2.0, 0.0, 0.0) N"
    assert vector([-1e-9], digits=2) == "(0.00)"                      # no "-0.00"
    assert number(np.float64(30e3), "kPa", 1e-3) == "30.0 kPa"
    assert one_of(("a", "b")) == "{a | b}"


def _fem_result():
    stats = SimpleNamespace(steps=[1, 2], t_total=1.0, t_linear=0.5, t_assembly=0.3)
    return SimpleNamespace(tip_position=np.array([0.1717, 1.86e-14, -0.03112]),
                           cap_rotation_vector=np.array([0.0, -0.3, 1e-12]), tensions=np.array([2.0, 0.0, 0.0]),
                           tendon_lengths=np.array([0.1595, 0.16, 0.16]), iterations=7, stats=stats,
                           loadcase=SimpleNamespace(pressure=30e3), state=SimpleNamespace(T=np.array([2.0, 0.0, 0.0])))


def test_fem_solve_text_and_figure_title():
    from validation.commands.fem import summary_lines
    from fem_reference.render import result_title
    res = _fem_result()
    text = "\n".join(summary_lines(res))
    assert_no_repr(text)
    assert "tip position: (171.70, 0.00, -31.12) mm" in text and "tensions: (2.000, 0.000, 0.000) N" in text
    title = result_title(res)
    assert_no_repr(title)
    assert title == "p = 30.0 kPa, T = (2.00, 0.00, 0.00) N, tip = (171.7, 0.0, -31.1) mm"


def run(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return info.value.code, out.out + out.err


@pytest.mark.parametrize("args", [("compliance", "--tensions-n", "1,0,0", "--pressure-kpa", "20"),
                                  ("fk", "--tensions-n", "1,0,0")])
def test_ancf_commands_print_no_repr(capsys, args):
    code, text = run(capsys, *args)
    assert code == 0, text
    assert_no_repr(text)


def test_demo_notes_print_no_repr(capsys, tmp_path):
    code, text = run(capsys, "demo", "--out", tmp_path)
    assert code == 0, text
    assert_no_repr(text)
    assert re.search(r"IK to \(\d+\.\d, -?\d+\.\d, -?\d+\.\d\) mm", text)


def test_control_status_and_header_print_no_repr(capsys):
    from validation.commands.control import _status_printer
    buf = io.StringIO()
    _status_printer(buf, every_s=0.0)({"t": 1.0, "iteration": 2, "error_m": 1e-4, "mode": "lacc",
                                       "estimate_N": np.array([0.1, -0.2, 0.3]), "pressure_Pa": 30e3})
    assert_no_repr(buf.getvalue())
    assert "(+0.100, -0.200, +0.300) N" in buf.getvalue()
    tip = Model(presets.paper()).fk((1.0, 1.0, 1.0), 30e3).tip
    code, text = run(capsys, "control", "--target-mm", ",".join(f"{x * 1e3:.3f}" for x in tip), "--pressure-kpa", 30,
                     "--fast", "--max-iterations", 1)
    assert code in (0, 1), text
    assert_no_repr(text)
    assert "target (" in text


def test_compare_figure_title_prints_no_repr(monkeypatch, tmp_path):
    from validation.paper import plots
    titles = []

    def capture(fig, out, stem):
        titles.extend(ax.get_title() for ax in fig.axes)
        return []
    monkeypatch.setattr(plots, "_save_figure", capture)
    res = {"paper": {"convergence_n6_mm": 0.3}, "labels": {"convergence_n6_mm": "tip error n = 6 [mm]"},
           "criteria": {"convergence_n6_mm": [0.15, 0.6]}, "settings": {"samples_per_mode_per_seed": 10, "seeds": [0, 1]},
           "presets": [{"preset": "p", "numbers": {"convergence_n6_mm": 0.31}, "verdicts": {}, "reproduced": 1,
                        "judged": 1}]}
    plots.plot_comparison(res, tmp_path)
    assert titles and all(REPR.search(t) is None for t in titles), titles


@pytest.mark.parametrize("call", [
    lambda m: m.ik(target=(0.158, 0.0, 0.012), pressure=30e3),                         # unreachable target
    lambda m: m.fk_locked(tendon_lengths=(-0.1, 0.16, 0.16)),                           # impossible lengths
])
def test_error_messages_print_no_repr(call):
    from ancf.errors import BellowsError
    with pytest.raises(BellowsError) as info:
        call(Model(presets.paper()))
    text = re.sub(r"\[-?[\d.]+, -?[\d.]+\] (N|kPa)", "<interval>", str(info.value))   # "[0, 5] N": a range
    assert_no_repr(text)
    assert " mm" in str(info.value)
