"""validation.control_studies: structure, units and the qualitative claims of Table I / Sec. V-E."""

import json

import pytest

from validation import control_studies as cs

CONFIGS = ("upward", "horizontal", "downward")


@pytest.fixture(scope="module")
def t1(tmp_path_factory):
    out = tmp_path_factory.mktemp("t1")
    return cs.table1(out=out), out


def test_table1_layout_and_units(t1):
    res, out = t1
    for c in CONFIGS:
        r = res[c]
        assert len(r["vfcc_history"]) == len(r["lacc_history"]) == 6          # initial + 5 iterations
        assert 1e-4 < r["vfcc_error"] < 0.05                                    # metres, not mm
        assert r["vfcc_mm"] == pytest.approx(1e3 * r["vfcc_error"])
        assert r["reduction"] == pytest.approx(1 - r["lacc_error"] / r["vfcc_error"])
        assert r["paper"]["vfcc_mm"] > 0
    assert "VF-CC" in res["table"]
    data = json.loads((out / "table1.json").read_text())
    assert set(CONFIGS) <= set(data)
    assert (out / "table1.png").stat().st_size > 1000


def test_table1_claims(t1):
    res, _ = t1
    for c in CONFIGS:
        r = res[c]
        # VF-CC (χ = 10 N/m) removes a few % at most; LACC shrinks the error every iteration
        assert r["vfcc_error"] > 0.8 * r["uncompensated_error"]
        h = r["lacc_history"]
        assert all(b < a for a, b in zip(h[:-1], h[1:]))
        assert r["lacc_error"] < 0.5 * r["vfcc_error"]
        assert r["lacc_exact_error"] < 2e-5                                      # Newton-like with exact C'_p


def test_ablation_quick():
    res = cs.compliance_ablation(loads_per_configuration=1, configurations={"horizontal": cs.CONFIGURATIONS["horizontal"]})
    m = res["methods"]
    assert m["exact"]["mean_iterations"] <= 2
    assert m["ik"]["mean_iterations"] > m["exact"]["mean_iterations"]
    assert "ik_faster_percent" in res


def test_loading_quick(tmp_path):
    res = cs.loading(ramp_up=2.0, ramp_down=1.0, cycles=1, frequency=0.5, cyclic_mass=0.05, loop_periods=(0.5,),
                     compare_exact=False, sample_dt=0.1, out=tmp_path)
    for k in ("continuous", "cyclic"):
        r = res[k]
        assert r["max_error"] < r["uncontrolled_max_drift"]
        assert r["corrections"] > 0
    assert res["compute_ms_median"] > 0.1                     # a real solver clock, not idle checks
    assert res["bandwidth"][0]["median_cycle_s"] == pytest.approx(0.5, rel=0.2)
    assert (tmp_path / "loading.json").exists() and (tmp_path / "loading.png").exists()


def test_paper_module_forwards():
    paper = pytest.importorskip("validation.paper")
    res = paper.table1(iterations=1, configurations={"downward": cs.CONFIGURATIONS["downward"]})
    assert "downward" in res and len(res["downward"]["lacc_history"]) == 2
