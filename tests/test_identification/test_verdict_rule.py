"""The verdict rule of the validation: a state passes when model error + FEM error ≤ target, fails when model
error − FEM error > target, and is undecided in between — its boundaries and monotonicity as properties; the
headline lists failures (naming the locked compliance and the FEM's error beside each number) before what is
undecided and what passes; the command line names the quantities."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf.errors import InputError
from validation.checks.fem_error import FemErrorEstimate, VERDICTS, assess, verdict
from validation.report.build import headline

from test_report_sentences import L, _row, _validation

errors = st.floats(0.0, 100.0, allow_nan=False)
targets = st.floats(0.1, 50.0, allow_nan=False)
RANK = {v: i for i, v in enumerate(VERDICTS)}                    # passes < undecided < fails


@settings(max_examples=300, deadline=None)
@given(m=errors, f=errors, t=targets)
def test_the_three_way_rule_is_its_definition(m, f, t):
    v = verdict(m, f, t)
    assert (v == "passes") == (m + f <= t)
    assert (v == "fails") == (m - f > t)
    assert (v == "undecided") == (m + f > t >= m - f)
    assert verdict(m, 0.0, t) == ("passes" if m <= t else "fails")           # an exact FEM decides every state


@settings(max_examples=300, deadline=None)
@given(m1=errors, m2=errors, f=errors, t=targets)
def test_a_larger_model_error_never_gives_a_better_verdict(m1, m2, f, t):
    lo, hi = sorted((m1, m2))
    assert RANK[verdict(lo, f, t)] <= RANK[verdict(hi, f, t)]


@settings(max_examples=300, deadline=None)
@given(m=errors, f1=errors, f2=errors, t=targets)
def test_a_larger_fem_error_only_moves_a_verdict_towards_undecided(m, f1, f2, t):
    lo, hi = sorted((f1, f2))
    a, b = verdict(m, lo, t), verdict(m, hi, t)
    assert a == b or b == "undecided"


@given(ti=st.integers(2, 4000), fi=st.integers(1, 4000))
def test_the_boundaries(ti, fi):
    """On exactly representable numbers (multiples of 1/64): m + f = t passes, m − f = t is undecided, just
    beyond either boundary the verdict changes."""
    t, f = ti / 64, fi / 64
    if t - f > 0:
        assert verdict(t - f, f, t) == "passes"
        assert verdict(t - f + 1 / 64, f, t) == "undecided"
    assert verdict(t + f, f, t) == "undecided"                  # m − f = t: not beyond the target
    assert verdict(t + f + 1 / 64, f, t) == "fails"
    assert verdict(t, f, t) == "undecided"


def test_bad_inputs_are_refused_and_a_missing_model_error_is_not_checked():
    assert verdict(None, 0.1, 2.5) is None and verdict(float("nan"), 0.1, 2.5) is None
    for m, f, t in ((1.0, -0.1, 2.5), (1.0, float("nan"), 2.5), (1.0, 0.1, 0.0), (1.0, 0.1, float("inf")),
                    (-1.0, 0.1, 2.5), (1.0, None, 2.5)):
        with pytest.raises(InputError):
            verdict(m, f, t)


# ----------------------------------------------------------------------------------------- headline and CLI
def _estimate(label: str, *, tip: float, cl: float, ct: float, deformation: float = 0.05) -> FemErrorEstimate:
    """A measured FEM error on one state, as estimate_fem_error reports it (no solve)."""
    by = {d: {"tip_error_pct": tip * w, "tip_error_m": tip * w * L / 100, "shape_error_pct": tip * w,
              "C_tension_error_pct": ct * w, "C_locked_error_pct": cl * w, "rate": 2.0} for d, w in
          (("along", 0.6), ("through", 0.4))}
    row = {"label": label, "deformation_m": deformation, "tip_error_m": tip * L / 100, "tip_error_pct": tip,
           "shape_error_pct": tip, "C_tension_error_pct": ct, "C_locked_error_pct": cl, "rate": 2.0,
           "rate_observed": False, "by_direction": by, "error": ""}
    return FemErrorEstimate([row], L, ["coarse"], "synthetic")


@pytest.fixture()
def judged():
    """h7 fails on the locked compliance (17.1 % − 0.9 % > 5 %), is undecided on the tension-held one
    (4.6 % ± 0.7 % straddles 5 %); its tip (0.58 % of L with the FEM's 1.15 %) passes."""
    rows = [_row("h7", (4, 4, 4), 83.3, shape=1.16, ct=4.6, cl=17.1, kz_locked=12.0),
            _row("h1", (1, 2.5, 0), 12.5, shape=0.4, ct=2.0, cl=3.0)]
    val = _validation(rows)
    from validation.reference.fem_sweep import FemRecord
    from validation.reference.experiments import LoadCase
    recs = []
    for lab, bend in (("h7", 0.05), ("h1", 0.01)):
        s = np.linspace(0, L, 5)
        line = np.column_stack([s, np.zeros(5), bend * (s / L) ** 2])
        recs.append(FemRecord(LoadCase((0.0,) * 3, 0.0, (0.0,) * 3, False, "x", "heldout", lab), line[-1], np.eye(3),
                              line, s, np.zeros(3), np.zeros(3)))
    val.fem_error = assess(val, _estimate("h7", tip=1.15, cl=0.9, ct=0.7), recs)
    return val


def test_the_headline_lists_failures_first_names_the_locked_compliance_and_the_fem_error(judged):
    h = headline(judged)
    assert [i["text"].split(":")[0] for i in h["fails"]] == ["Locked compliance"]
    fail = h["fails"][0]["text"]
    assert "17.1 %" in fail and "state h7" in fail and "5 % target" in fail and f"{17.1 / 5:.1f} × the target" in fail
    assert "the FEM's own error there ±0.9 %, measured" in fail and "LACC" in fail
    undecided = " | ".join(i["text"] for i in h["undecided"])
    assert undecided.startswith("Tension-held compliance: undecided on 1 of 2 states") and "±0.7 %" in undecided
    assert "3.9 % … 5.3 %" in undecided and "a finer FEM mesh decides" in undecided
    passes = " | ".join(i["text"] for i in h["passes"])
    assert "Tip position: worst error 0.58 % of L at state h7" in passes and "±1.15 % of L" in passes
    # the unmeasured h1 carries an estimate: 1.15 % of L × (10 mm / 50 mm) of deformation
    h1 = next(r for r in judged.fem_error["rows"] if r["label"] == "h1")
    assert h1["fem_tip_error_pct"] == pytest.approx(1.15 * 0.01 / 0.05) and "estimate" in h1["basis"]
    assert not any("too large" in i["text"] for k in ("fails", "undecided", "passes") for i in h[k])
    assert "FEM discretisation error measured on the 1 most deformed" in h["notes"][0]


def test_the_report_shows_fails_then_undecided_then_passes_and_no_red_on_a_passing_state(judged, tmp_path):
    import re
    from validation.report.build import build_report
    from validation.identification import identify
    from validation.reference.experiments import default_design
    from test_report_cli import _states
    from test_report_sentences import MASSED
    ident = identify.from_measurements(_states(default_design()), MASSED, forms=("separate",), gravity=False)
    html = build_report(ident, judged, figures={})
    text = " ".join(re.sub(r"<[^>]+>", " ", html).split())
    i_fail, i_und, i_pass = (text.index(s) for s in ("Fails, worst first", "Undecided (the FEM's own error",
                                                       "Passes:"))
    assert i_fail < i_und < i_pass
    assert "too large" not in text and "a third" not in text
    row_h1 = re.search(r"<tr><td class=\"l\">h1</td>.*?</tr>", html, re.S).group(0)
    assert "all pass" in row_h1 and 'class="bad"' not in row_h1 and 'class="l bad"' not in row_h1


def test_the_command_line_names_the_locked_compliance(judged, monkeypatch):
    from rich.console import Console
    import validation.commands.identify as cmd
    rec = Console(record=True, width=300)
    monkeypatch.setattr(cmd, "console", rec)
    cmd._print_validation(judged)
    out = rec.export_text()
    assert "locked compliance < 5 %: FAILS — 1 pass, 1 fail, 0 undecided; fails: h7" in out
    assert "tension-held compliance < 5 %: UNDECIDED" in out and "tip position < 2.5 % of L: passes" in out
    assert "compliance_pct" not in out and "NOT met" not in out
