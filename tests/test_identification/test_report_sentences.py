"""Every sentence of the report that states physics or a verdict comes from the data it describes, and the
headline lists what fails first.

Built from the report's pieces on small synthetic inputs (a validation written by hand, the rod's modes of a
law with and without a pressure factor on EI); the numbers a sentence states are checked against closed forms
(the pressure factor's polynomial, √EI for a frequency, one scalar step of LACC's load update), never against
the report's own output.  One slow test reads a real quick report."""

import math
import os
import pathlib
import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from validation.checks.compare import ValidationResult, _target, ratio_row
from validation.checks.modes_compare import compare_modes, modes_sentences, pressure_factor_text
from validation.identification import identify
from validation.reference.experiments import default_design
from validation.report.build import _law_dependence, _provenance_rows, _ratio_note, build_report, headline, sections

from test_fit import BASE
from test_report_cli import _states

L = 0.16
MASSED = BASE.replace(line_mass=0.3, tip_mass=0.01)
#: the chosen `pressure_ei` form of the default bellows: EI × (1 + 0.71 p̂ + 0.50 p̂²)
PRESSURE_EI = (0.71, 0.50)


def _with_ei(params, coeffs):
    return params.replace(stiffness=params.stiffness.with_pressure(EI=coeffs))


# ----------------------------------------------------------------------------------------- synthetic validation
def _row(label, T, p_kpa, *, shape=0.5, ct=2.0, cl=3.0, kz_locked=5.0, kz_tension=1.0):
    return {"label": label, "experiment": "heldout", "tensions_N": list(T), "pressure_Pa": 1e3 * p_kpa,
            "tip_force_N": [0.0, 0.0, 0.0], "gravity": False, "tip_error_m": 0.5 * shape * L / 100,
            "tip_error_pct": 0.5 * shape, "shape_error_m": shape * L / 100, "shape_error_pct": shape,
            "C_tension_error_pct": ct, "C_locked_error_pct": cl, "k_locked_z_error_pct": kz_locked,
            "k_tension_z_error_pct": kz_tension, "ratio_z_fem": 2.0, "ratio_z_ancf": 2.2}


def _validation(rows, params=BASE, fem_error=None) -> ValidationResult:
    """A ValidationResult as compare_records fills it, from hand-written rows (verdicts by its own rule)."""
    stats = lambda k: {"mean": float(np.mean([r[k] for r in rows])), "max": float(max(r[k] for r in rows))}  # noqa: E731
    v = ValidationResult(rows=rows, length=L, params=params)
    v.tip_error_pct, v.shape_error_pct = stats("tip_error_pct"), stats("shape_error_pct")
    v.compliance_error_pct = {m: stats(f"C_{m}_error_pct") for m in ("tension", "locked")}
    v.ratio = {"fem": stats("ratio_z_fem"), "ancf": stats("ratio_z_ancf")}
    v.ratio_per_state = [ratio_row(r) for r in rows]
    v.targets = {"shape_pct": _target(2.5, v.shape_error_pct["max"], []),
                 "compliance_pct": _target(5.0, max(v.compliance_error_pct["tension"]["max"],
                                                    v.compliance_error_pct["locked"]["max"]), [])}
    v.fem_error = fem_error or {}
    return v


def _one_lacc_step(k_model_over_plant: float) -> float:
    """Tip error left after one scalar LACC step ΔF̂ = e / C_model on a plant of compliance C_plant, as a
    share of the error before: e − C_plant ΔF̂ = (1 − k_model / k_plant) e."""
    c_plant, c_model, e = 1.0, 1.0 / k_model_over_plant, 1.0
    dF = e / c_model
    return e - c_plant * dF


def test_the_headline_names_the_locked_compliance_its_state_target_and_meaning_for_lacc():
    rows = [_row("h1", (1, 2.5, 0), 12.5, shape=0.9, ct=4.5, cl=5.7, kz_locked=3.0),
            _row("h7", (4, 4, 4), 83.3, shape=0.2, ct=4.9, cl=17.1, kz_locked=12.0)]
    h = headline(_validation(rows))
    assert len(h["fails"]) == 1
    fail = h["fails"][0]["text"]
    assert fail.startswith("Locked compliance")
    assert "17.1 %" in fail and "state h7 (T = (4, 4, 4) N, p = 83.3 kPa)" in fail
    assert "5 % target" in fail and f"{17.1 / 5:.1f} × the target" in fail
    assert "stiffer" in fail and "LACC" in fail and "ΔF̂ = C'_p⁻¹ e" in fail
    left = _one_lacc_step(1.12)                                  # k_model / k_FEM = 1 + 12 %
    assert f"about {100 * left:+.0f} % of a vertical error" in fail and "overshooting" in fail
    passes = " | ".join(i["text"] for i in h["passes"])
    assert "Tension-held compliance: worst error 4.9 % at state h7" in passes
    assert "Shape: worst error 0.90 % of L" in passes and "state h1 (T = (1, 2.5, 0) N, p = 12.5 kPa)" in passes
    assert not h["incomplete"]


def test_failures_come_worst_first_and_each_compliance_says_what_the_controller_does_with_it():
    rows = [_row("a", (0, 2, 4), 37.5, ct=30.0, cl=6.0, kz_locked=-20.0)]
    h = headline(_validation(rows))
    assert [i["text"].split(":")[0] for i in h["fails"]] == ["Tension-held compliance", "Locked compliance"]
    held, locked = (i["text"] for i in h["fails"])
    assert "taut" in held and "ΔF̂" not in held
    assert "softer" in locked and "falling short" in locked
    assert f"about {100 * _one_lacc_step(0.80):+.0f} % of a vertical error" in locked       # +20 %


def test_a_label_that_states_the_loads_is_not_followed_by_them_again():
    h = headline(_validation([_row("T=4/4/4 N, p=83.3 kPa", (4, 4, 4), 83.3, cl=17.1)]))
    assert "at state T=4/4/4 N, p=83.3 kPa against the 5 % target" in h["fails"][0]["text"]


def test_an_incomplete_target_is_not_checked_and_not_a_failure():
    v = _validation([_row("a", (1, 0, 0), 10, cl=9.0)])
    v.targets["compliance_pct"] = _target(5.0, float("nan"), ["b"])
    h = headline(v)
    assert not h["fails"] and "not checked on b" in h["incomplete"][0]["text"]


def test_the_fem_error_line_is_the_rule_of_the_data_not_a_fixed_sentence():
    fe = {"estimated": True, "n_measured": 2, "max_fem_tip_error_pct": 0.012, "rule": "RULE-FROM-DATA",
          "rows": [{"label": "a", "fem_by_direction": {"along": {"tip_error_pct": 0.01},
                                                       "through": {"tip_error_pct": 0.004}}}]}
    h = headline(_validation([_row("a", (1, 0, 0), 10)], fem_error=fe))
    note = h["notes"][0]
    assert "0.01 % of L" in note and "RULE-FROM-DATA" in note and "along up to 0.01 %" in note
    assert "through up to 0.00 %" in note and "a third" not in note and "too large" not in note
    assert "not estimated" in headline(_validation([_row("a", (1, 0, 0), 10)],
                                                   fem_error={"estimated": False}))["incomplete"][0]["text"]


# ----------------------------------------------------------------------------------------- the rendered report
@pytest.fixture(scope="module")
def ident():
    return identify.from_measurements(_states(default_design()), MASSED, forms=("separate",), gravity=False)


def _text(html):
    return " ".join(re.sub(r"<[^>]+>", " ", html).split())


def test_the_report_opens_with_failures_then_passes_and_every_link_lands(ident):
    rows = [_row("h1", (1, 2.5, 0), 12.5, ct=4.5, cl=5.7), _row("h7", (4, 4, 4), 83.3, ct=4.9, cl=17.1)]
    html = build_report(ident, _validation(rows, ident.params), figures={})
    text = _text(html)
    i_fail, i_pass, i_params = (text.index(s) for s in ("Fails, worst first", "Passes", "1. Identified parameters"))
    assert i_fail < i_pass < i_params
    assert text.index("Locked compliance: error 17.1 %") < text.index("Tension-held compliance: worst error 4.9 %")
    hrefs = re.findall(r'href="#([^"]+)"', html)
    ids = set(re.findall(r'id="([^"]+)"', html))
    assert hrefs and set(hrefs) <= ids
    for sid in ("sec-params", "sec-forms", "sec-validation", "sec-fem-error", "sec-ratio", "sec-diagnostics",
                "sec-provenance"):
        assert f'href="#{sid}"' in html and f'id="{sid}"' in html
    assert re.search(r'<h3 id="sec-fem-error">3a\. The FEM', html)


def test_sections_are_numbered_in_order_whatever_is_shown():
    titles = [t["title"] for t in sections(None, None, {"rows": []}, False)]
    assert titles == ["1. Identified parameters", "2. Model forms compared", "3. Dynamics: first modes per pressure",
                      "4. Diagnostics", "Provenance"]
    v = ValidationResult(rows=[], length=L, params=BASE)
    titles = [t["title"] for t in sections(v, {"x": 1}, None, True)]
    assert titles[2:7] == ["3. Reduced model vs FEM on held-out states", "3a. The FEM's own discretisation error",
                           "3b. Locked / tension-held vertical stiffness ratio per state",
                           "4. Stiffness vs tendon tension (the Fig. 9 protocol)", "5. Diagnostics"]


def test_provenance_lists_the_command_once(ident):
    ident.meta["command"] = "bellows report --quick"
    try:
        rows = _provenance_rows(ident, "bellows report --quick")
        html = build_report(ident, figures={}, command="bellows report --quick")
    finally:
        del ident.meta["command"]
    assert [k for k, _ in rows].count("command") == 1
    assert html.count("<td class=\"l\">command</td>") == 1


def test_the_ratio_paragraph_says_what_the_chosen_model_does_with_shear(ident):
    from ancf.shear import compliance
    sc = (0.5e-3, 3.3e-3)
    rows = [_row("h1", (1, 0, 0), 20)]
    for params, expect, absent in ((ident.params, "has no shear compliance", "series shear compliance"),
                                   (ident.params.replace(shear_compliance=sc), "series shear compliance",
                                    "has no shear compliance")):
        v = _validation(rows, params)
        section = _text(build_report(ident, v, figures={})).split("3b. Locked")[-1].split("k_z with", 1)[1][:900]
        assert expect in section and absent not in section and "no term for" not in section
    assert f"{1e3 * compliance(sc, 100e3):.2f}" == "3.80"


def test_the_diagnostics_state_the_laws_own_dependence_and_the_ratios_order():
    assert _law_dependence(BASE, "EI") == "the law's dependence on stretch alone"
    d = _law_dependence(_with_ei(BASE, PRESSURE_EI), "EI")
    assert "stretch and pressure" in d and "1 + 0.71 p̂ + 0.50 p̂²" in d
    assert _law_dependence(_with_ei(BASE, PRESSURE_EI), "EA") == "the law's dependence on stretch alone"
    v = _validation([_row("a", (1, 0, 0), 10)])
    assert "FEM's ratio is the lower one" in _ratio_note(v)                    # FEM 2.0 < model 2.2
    v.ratio = {"fem": {"mean": 2.5, "max": 2.5}, "ancf": {"mean": 2.2, "max": 2.2}}
    assert "FEM's ratio is the lower" not in _ratio_note(v)


# ----------------------------------------------------------------------------------------- the Dynamics sentences
def _fake_fem(pressures, bending=3.0, axial=25.0):
    return [{"pressure_Pa": p, "bending_hz": bending * 1.1 ** k, "axial_hz": axial, "frequencies_hz": [1.0],
             "total_mass_kg": 0.06, "seconds": 0.0, "error": ""} for k, p in enumerate(pressures)]


PRESSURES = [0.0, 50e3, 100e3]


@pytest.fixture(scope="module")
def modes_pair():
    """The rod's modes (stand-in FEM rows) of one law without and with the pressure factor on EI."""
    return {name: compare_modes(p, PRESSURES, [0.0] * 3, fem=_fake_fem(PRESSURES))
            for name, p in (("stretch", MASSED), ("pressure", _with_ei(MASSED, PRESSURE_EI)))}


def test_the_dynamics_sentences_follow_the_fitted_pressure_factor(modes_pair):
    """For EI × (1 + 0.71 p̂ + 0.50 p̂²) no sentence says EI depends on the stretch only; the factor and what it
    does to a frequency (√f_I) are stated, and the rod's own modes confirm the √f_I."""
    with_p = " ".join(modes_sentences(modes_pair["pressure"]))
    without = " ".join(modes_sentences(modes_pair["stretch"]))
    assert "stretch only" not in with_p and "not on the pressure" not in with_p
    assert "EI(λ) has no pressure factor" not in with_p and "EI has no pressure factor" not in with_p
    f = 1 + 0.71 + 0.50                                            # f_I at p̂ = 1
    assert "1 + 0.71 p̂ + 0.50 p̂²" in with_p and f"at 100 kPa it is {f:.2f} × EI(λ), stiffer" in with_p
    assert f"{100 * (math.sqrt(f) - 1):+.0f} % at equal length" in with_p
    a, b = (m["rows"][-1]["rod_bending_frequency_hz"] for m in (modes_pair["pressure"], modes_pair["stretch"]))
    assert a / b == pytest.approx(math.sqrt(f), rel=5e-3)          # the same straight state: f ∝ √EI
    assert "has no pressure factor" in without and "carries the fitted pressure factor" not in without
    # the FEM stand-in stiffens 21 %: the stretch-only rod falls behind, the pressure rod outruns it
    assert "the FEM stiffens in bending with pressure and the rod's EI has no pressure factor" in without
    assert "the rod stiffens in bending with pressure more than the FEM" in with_p
    assert modes_pair["pressure"]["rod_EI_pressure_coeffs_per_100kPa"] == list(PRESSURE_EI)


def test_a_modes_record_without_the_factors_claims_nothing_about_them(modes_pair):
    old = {k: v for k, v in modes_pair["pressure"].items() if not k.startswith("rod_E")}
    text = " ".join(modes_sentences(old))
    assert "pressure factor" not in text and "stretch only" not in text
    assert "change differently with pressure" in text or "hardly changes" in text


def _modes_dict(ei, rod=(3.0, 3.2, 3.5)):
    rows = [{"pressure_kPa": p, "rod_bending_frequency_hz": f, "fem_bending_frequency_hz": None,
             "bending_difference_pct": None, "axial_difference_pct": None} for p, f in zip((0.0, 50.0, 100.0), rod)]
    return {"rows": rows, "fem": "not computed", "rod_EI_pressure_coeffs_per_100kPa": list(ei),
            "rod_EA_pressure_coeffs_per_100kPa": []}


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([0.0, -0.3, 0.25, 0.71, 0.5, 1.2]), min_size=0, max_size=3))
def test_the_law_sentence_never_contradicts_the_coefficients(ei):
    text = " ".join(modes_sentences(_modes_dict(ei)))
    factors = {p: 1 + sum(c * (p / 100) ** j for j, c in enumerate(ei, start=1)) for p in (0.0, 50.0, 100.0)}
    if not any(ei):
        assert "has no pressure factor" in text and "carries" not in text
        return
    assert "carries the fitted pressure factor" in text and "no pressure factor" not in text
    p, f = max(factors.items(), key=lambda kv: abs(kv[1] - 1))
    if abs(f - 1) >= 5e-3:
        assert f"at {p:g} kPa it is {f:.2f} × EI(λ), {'stiffer' if f > 1 else 'softer'}" in text
    assert pressure_factor_text(ei) in text


# ----------------------------------------------------------------------------------------- a real quick report
def check_real_report(folder, pressure_ei=None) -> None:
    """The checks of a real report folder (report.html, validation.json, actuator.toml): the headline names the
    locked compliance among its failures when its verdict fails (or states its worst value when it passes), the Dynamics sentences state the
    chosen law's own EI pressure factor, the command is listed once, every section link lands."""
    import json
    from ancf import ActuatorParams
    folder = pathlib.Path(folder)
    html = (folder / "report.html").read_text()
    text = _text(html)
    v = json.loads((folder / "validation.json").read_text())
    c, q = v["compliance_error_pct"], v["fem_discretisation_error"]["quantities"]
    # the locked compliance, when it fails (model − FEM error > target), heads the headline's failures; when
    # every state passes, its worst error is stated as passing
    locked = q["C_locked"]
    if locked["fails"]:
        fails = text.split("Fails, worst first:")[1]
        assert "Locked compliance: error" in fails.split("Passes:")[0], fails[:200]
    elif not locked["undecided"]:
        assert f"Locked compliance: worst error {c['locked']['max']:.1f} %" in text
    ei = list(ActuatorParams.from_toml(folder / "actuator.toml").stiffness.EI_pressure)
    if pressure_ei is not None:
        assert ei == pytest.approx(pressure_ei, abs=0.005)
    dyn = text.split("Dynamics: first modes per pressure")[-1].split("Diagnostics")[0]
    if any(ei):
        assert pressure_factor_text(ei) in dyn and "EI(λ) has no pressure factor" not in dyn
        assert "stretch only" not in text
    else:
        assert "EI(λ) has no pressure factor" in dyn
    assert html.count("<td class=\"l\">command</td>") <= 1
    assert set(re.findall(r'href="#([^"]+)"', html)) <= set(re.findall(r'id="([^"]+)"', html))


@pytest.mark.slow
def test_a_real_quick_report_headline_and_dynamics_match_its_files(tmp_path_factory):
    """`bellows report --quick` on the default design (minutes with an empty cache; seconds with the FEM cache
    of an earlier quick report of the same code in $BELLOWS_FEM_CACHE): :func:`check_real_report`, the chosen
    `pressure_ei` form's EI × (1 + 0.71 p̂ + 0.50 p̂²) stated as such."""
    from validation.report.pipeline import run_report
    cache = pathlib.Path(os.environ.get("BELLOWS_FEM_CACHE") or tmp_path_factory.mktemp("fem_cache"))
    run = run_report(tmp_path_factory.mktemp("rq") / "report", quick=True, cache_dir=cache, command="bellows report")
    check_real_report(run.out, PRESSURE_EI if run.identification.form == "pressure_ei" else None)
    assert run.report.read_text().count("<td class=\"l\">command</td>") == 1


def test_the_choice_rule_sentence_follows_what_the_forms_were_compared_on():
    """The report's model-selection sentence is made from the comparison rows: with a held-out compliance error on
    every fitted form the choice weighed it (and the sentence says so); without, the tip error alone."""
    from types import SimpleNamespace
    from validation.report.build import choice_rule
    both = SimpleNamespace(comparison=[{"form": "a", "heldout_rms_tip_m": 1e-3, "heldout_compliance_error_pct": 5.0},
                                       {"form": "b", "heldout_rms_tip_m": 2e-3, "heldout_compliance_error_pct": 4.0}])
    tip = SimpleNamespace(comparison=[{"form": "a", "heldout_rms_tip_m": 1e-3},
                                      {"form": "b", "heldout_rms_tip_m": 2e-3, "heldout_compliance_error_pct": 4.0}])
    train = SimpleNamespace(comparison=[{"form": "a", "train_rms_tip_m": 1e-3}])
    assert "compliance" in choice_rule(both) and "held-out RMS tip error" in choice_rule(both)
    assert "compliance" not in choice_rule(tip) and "held-out RMS tip error" in choice_rule(tip)
    assert "training" in choice_rule(train)
