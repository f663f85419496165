"""The coverage study's design and scoring (benchmark j), without any FE solve (a second).

    pytest benchmarks/test_coverage_design.py

Not part of the test suite (``testpaths = tests``), like ``benchmarks/test_benchmarks.py``.
"""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace

import pandas as pd

from jointid.diagnosis.effects import EFFECTS, enabled_effects
from jointid.synthetic.generate import check_truth

from .bench_j_coverage import (NOISE_FACTORS, QUICK_CASES, SIZES, design, metrics, named_effects, select,
                               summary_tables, truth_of)


def test_design_has_every_required_stratum():
    cases = design()
    assert len(cases) >= 40
    assert len({c["case"] for c in cases}) == len(cases) and len({c["seed"] for c in cases}) == len(cases)
    kinds = Counter(c["kind"] for c in cases)
    assert kinds["none"] >= 8 and kinds["pair"] >= 4
    singles = Counter(next(iter(c["effects"])) for c in cases if c["kind"] == "single")
    assert set(singles) == set(EFFECTS) == set(SIZES)  # every library effect alone
    for kind in ("single", "pair", "none"):
        of_kind = [c for c in cases if c["kind"] == kind]
        assert {c["noise"] for c in of_kind} == set(NOISE_FACTORS), kind
        assert {c["shapes"] for c in of_kind} == {True, False}, kind
    assert {c["max_modes"] for c in cases} == {4, 5, 6, 7, 8}
    assert design() == cases  # deterministic


def test_truths_are_valid_and_inside_the_bounds():
    for c in design():
        for rig in ("coarse", "default"):
            t = truth_of(c, rig)
            check_truth(t)
            assert t["overrides"]["mesh"]  # the truth on a finer mesh than the analysis
            f = NOISE_FACTORS[c["noise"]]
            assert t["noise"]["stated_frequency_pct"] == t["noise"]["frequency_pct"] * f
            assert t["noise"]["stated_shape_pct"] == t["noise"]["shape_pct"] * f
        enabled_effects(c["effects"])  # raises outside a parameter's bounds
        assert len(c["effects"]) == {"none": 0, "single": 1, "pair": 2}[c["kind"]]


def test_quick_and_prefix_selections():
    cases = design()
    quick = select(cases, True, None, "coarse")
    assert [c["case"] for c in quick] == list(QUICK_CASES)
    first = select(cases, False, 8, "coarse")
    assert {c["kind"] for c in first} == {"single", "pair", "none"}
    assert len(select(cases, False, None, "default")) == 8
    assert len(select(cases, False, None, "coarse")) == len(cases)


def _res(explained_by, effects, ties=("",) * 3):
    ranking = pd.DataFrame({"effect": effects, "indistinguishable_from": list(ties)[:len(effects)]})
    return SimpleNamespace(explained_by=explained_by, ranking=ranking)


def test_what_the_diagnosis_names():
    assert named_effects(_res("a", ["a", "b"]), ["a"]) == (["a"], "+a")
    assert named_effects(_res("a or b", ["a", "b"]), ["a", "b"]) == (["a", "b"], "+a")
    assert named_effects(_res("a+b", ["a", "b"]), ["a+b"]) == (["a", "b"], "+a+b")
    # unexplained, but something supported: the first supported with its tie
    assert named_effects(_res("unexplained", ["b", "a"], ["a", "b", ""]), ["b"]) == (["b", "a"], "+b")
    assert named_effects(_res("unexplained", ["b", "a"]), []) == ([], "current")
    assert named_effects(_res("none needed", ["b", "a"]), []) == ([], "current")


def test_metrics_and_cells():
    rows = []
    for i in range(10):
        rows.append({"kind": "single", "noise": "right", "shapes": True, "found": i < 9, "claimed": None,
                     "eff1": "a", "eff1_in": i < 8, "kn_rep_in": True, "kl_rep_in": i < 5,
                     "kn_true_in": True, "kl_true_in": True})
    for i in range(5):
        rows.append({"kind": "none", "noise": "small", "shapes": False, "found": None, "claimed": i == 0,
                     "eff1": None, "eff1_in": None, "kn_rep_in": True, "kl_rep_in": True,
                     "kn_true_in": True, "kl_true_in": True})
    df = pd.DataFrame(rows)
    m = metrics(df)
    assert m["found"] == (9, 10) and m["no_claim"] == (4, 5) and m["effect_ci"] == (8, 10)
    assert m["joint_ci"] == (25, 30)
    _, _, met = summary_tables(df)
    assert met["found"] and not met["no_claim"] and not met["effect_ci"] and not met["joint_ci"]
    assert not met["cells"]  # the noise-right cell: joints 15/20 = 75 % < 80 %


def test_judging_a_case_from_its_csv_columns():
    from .bench_j_coverage import judge

    assert judge("a", "a", "a", "a")["found"]
    assert judge("a", "a or b", "a;b", "a;b")["found"]  # a named tie that holds the truth
    assert judge("a", "unexplained", "a;b", "a")["found"]  # the supported one, named first
    j = judge("a", "a+b", "a+b;a", "a;b")  # a spurious second effect
    assert not j["found"] and j["found_loose"]
    assert judge("a+b", "b+a", "b+a", "b;a")["found"]
    assert not judge("a+b", "a", "a", "a")["found"]
    assert judge("none", "none needed", "", "")["claimed"] is False
    assert judge("none", "unexplained", "b", "b")["claimed"] is True
    assert judge("none", "ERROR ValueError", None, None)["claimed"] is True
    assert judge("a", "ERROR ValueError", None, None)["found"] is False
