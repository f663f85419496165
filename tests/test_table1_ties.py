"""Table 1's status when it rests on the choice among exactly tied pairings (verify -> harmonic -> table1)."""

import numpy as np
import pytest
import pandas as pd

from jointid.identification.record import IdentificationRecord
from jointid.identification.ties import TIE, tied_alternatives
from jointid.reporting.tables import table1_frame, table1_markdown
from jointid.stages.harmonic import tie_note
from jointid.stages.verify import tied_pairings

CANDIDATES = [{"pairing": [0, 2, 4], "cost": 0.5}, {"pairing": [0, 3, 4], "cost": 0.5 + TIE / 10},
              {"pairing": [0, 1, 4], "cost": 0.5}, {"pairing": [1, 2, 4], "cost": 0.51}]


def test_tied_alternatives_are_the_other_pairings_of_equal_cost():
    assert tied_alternatives(CANDIDATES, [0, 2, 4]) == [[0, 3, 4], [0, 1, 4]]
    assert tied_alternatives(CANDIDATES, [1, 2, 4]) == []  # nothing fits as well as it
    assert tied_alternatives(CANDIDATES, [9, 9, 9]) == []  # not among the candidates: nothing to compare


def test_tied_pairings_map_tracked_modes_to_fe_modes_by_shape():
    """Tracked modes 0..4 are the FE modes in the order [1, 0, 2, 4, 3] (by shape), so each tied
    pairing's columns land on those FE modes."""
    rng = np.random.default_rng(3)
    ref = np.linalg.qr(rng.standard_normal((12, 5)))[0]  # orthogonal shapes: MAC 1 with itself, ~0 else
    fe = ref[:, [1, 0, 2, 4, 3]]
    par = {"parameters": {}, "paired_by": "frequency, shared by all states", "pairing_columns": [0, 2, 4],
           "joint_pairing": {"candidates": CANDIDATES}}
    tied = tied_pairings(IdentificationRecord.from_json(par), {"ref_shapes": ref.tolist()}, fe)
    assert list(tied.columns) == ["alternative", "order", "fe_mode"]
    assert tied[tied.alternative == 1].fe_mode.tolist() == [2, 5, 4]  # columns [0, 3, 4] -> FE 2, 5, 4 (1-based)
    assert tied[tied.alternative == 2].fe_mode.tolist() == [2, 1, 4]  # columns [0, 1, 4]
    # a one-state frequency pairing (re-paired at the FE optimum) has no tie record to read
    assert tied_pairings(IdentificationRecord.from_json({**par, "paired_by": "frequency"}), {"ref_shapes": ref.tolist()},
                         fe).empty


def write_tied(tmp_path, rows):
    path = tmp_path / "tied.csv"
    pd.DataFrame(rows, columns=["alternative", "order", "fe_mode"]).to_csv(path, index=False)
    return str(path)


def test_tie_note_when_a_tied_pairing_pairs_the_unpaired_governing_mode(tmp_path):
    tied = write_tied(tmp_path, [(1, 1, 1), (1, 2, 2), (1, 3, 5), (2, 1, 1), (2, 2, 4), (2, 3, 5)])
    note = tie_note(tied, g=1, order=None, freq_Hz=1319.7)  # governing FE mode 2, unpaired in the chosen
    assert note["rests_on_tie"] and note["tied_pairings"] == 2
    assert "pairs the governing mode (FE mode 2, 1319.7 Hz) with measured mode 2" in note["note"]


def test_tie_note_when_a_tied_pairing_unpairs_the_paired_governing_mode(tmp_path):
    tied = write_tied(tmp_path, [(1, 1, 1), (1, 2, 4), (1, 3, 5)])
    note = tie_note(tied, g=2, order=2, freq_Hz=1395.2)  # FE mode 3 paired with measured mode 2 here
    assert note["rests_on_tie"]
    assert "leaves the governing mode (FE mode 3, 1395.2 Hz) without the measured partner 2" in note["note"]


def test_no_tie_note_when_the_ties_do_not_touch_the_governing_mode(tmp_path):
    tied = write_tied(tmp_path, [(1, 1, 1), (1, 2, 4), (1, 3, 5)])
    assert not tie_note(tied, g=0, order=1, freq_Hz=344.0)["rests_on_tie"]  # paired in both
    assert not tie_note(tied, g=6, order=None, freq_Hz=3800.0)["rests_on_tie"]  # unpaired in both
    empty = write_tied(tmp_path, [])
    assert tie_note(empty, g=1, order=None, freq_Hz=1319.7) == {"rests_on_tie": False, "note": "", "tied_pairings": 0,
                                                                  "rule": ""}
    assert not tie_note(None, g=1, order=None, freq_Hz=1319.7)["rests_on_tie"]


def stiffness_doc(state, tie):
    return {"state": state, "governing_mode": {"fe_mode": 2, "freq_Hz": 1319.7, "description": "table bounce",
                                               "damping_ratio": 0.03, "measured_order": None},
            "status": "not identified: the governing mode (FE mode 2, 1319.7 Hz, table bounce) has no measured partner",
            "dynamic_stiffness_N_per_m": 6.0e7, "static_stiffness_N_per_m": 4.0e8, "f_at_min_Hz": 1314.0,
            "paired_minimum": None, "damping": {"config": {"model": "modal"}}, "drive_point": "T05",
            "direction": "y", "patch_diameter_m": 0.01, "tie": tie}


def test_table1_carries_the_tie_and_says_it():
    tie = {"rests_on_tie": True, "note": "an exactly tied pairing pairs the governing mode (FE mode 2, 1319.7 Hz) "
                                         "with measured mode 2: frequencies alone cannot choose", "tied_pairings": 2}
    paper = pd.DataFrame({"state": ["power_off", "power_on"], "paper_dynamic_stiffness_N_per_mm": [104547.0, 148551.0]})
    df = table1_frame([stiffness_doc("power_off", tie), stiffness_doc("power_on", {"rests_on_tie": False, "note": ""})],
                      paper)
    assert df["status_rests_on_tie"].tolist() == [True, False]
    assert df["status"].str.startswith("not identified").all()  # the status itself is unchanged
    md = table1_markdown(df)
    assert "**power_off: the status rests on a tie.** An exactly tied pairing pairs the governing mode" in md
    assert "power_on: the status rests on a tie" not in md


def _par_resolvability():
    """params.json of a shared frequency pairing whose tie the resolvability rule decided: the chosen
    pairing [0, 1, 4] pairs the bounce (tracked 2); tied 1, [0, 2, 4], would leave it 7.2 % below
    measured mode 2, outside that peak's +-3 % half-power band."""
    seen = lambda f, off, hides: {"state": "power_off", "tracked_mode": 2 if hides is False else 3, "freq_Hz": f,  # noqa: E731
                                  "measured_order": 2, "measured_Hz": 1416.0, "offset_pct": off,
                                  "damping_ratio": 0.03, "hides": hides, "offset_nearest_pct": abs(off)}
    return {"parameters": {}, "paired_by": "frequency, shared by all states", "pairing_columns": [0, 1, 4],
            "joint_pairing": {"candidates": [{"pairing": [0, 1, 4], "cost": 0.5}, {"pairing": [0, 2, 4], "cost": 0.5}]},
            "tie_rule": {"rule": "resolvability", "tied": [
                {"pairing": [0, 1, 4], "resolvable": True, "unpaired_visible": [seen(1414.6, -0.10, True)],
                 "damping_ratio_needed": 0.001},
                {"pairing": [0, 2, 4], "resolvable": False, "unpaired_visible": [seen(1314.0, -7.20, False)],
                 "damping_ratio_needed": 0.072}]}}


def test_tie_note_says_the_resolvability_rule_chose_and_why(tmp_path):
    tied = write_tied(tmp_path, [(1, 1, 1), (1, 2, 4), (1, 3, 5)])  # tied 1 pairs FE mode 4 (not 3) with mode 2
    note = tie_note(tied, g=2, order=2, freq_Hz=1314.0, par=IdentificationRecord.from_json(_par_resolvability()))
    assert note["rests_on_tie"] and note["rule"] == "resolvability"
    assert note["note"] == ("an exactly tied pairing leaves the governing mode (FE mode 3, 1314.0 Hz) without the "
                            "measured partner 2 it has here: the fit cannot choose between them; the resolvability "
                            "rule did (that pairing leaves unpaired 1314 Hz (power_off), -7.2 % from measured "
                            "mode 2 (1416 Hz), outside its half-power band ±3.0 %: a peak the test would have "
                            "shown on its own); measured mode shapes would confirm it")
    fallback = {**_par_resolvability(), "tie_rule": {"rule": "nearest partners (fallback: none of the 2 tied "
                                                             "pairings lets every unpaired visible mode hide in a "
                                                             "measured peak)", "tied": []}}
    note = tie_note(tied, g=2, order=2, freq_Hz=1314.0, par=IdentificationRecord.from_json(fallback))
    assert note["rule"].startswith("nearest partners (fallback: none")
    assert note["note"].endswith("frequencies alone cannot choose between them (chosen by nearest partners "
                                 "(fallback: none of the 2 tied pairings lets every unpaired visible mode hide in a "
                                 "measured peak)), measured mode shapes would")


def test_pairing_orders_give_each_tied_pairing_its_partners(tmp_path):
    from jointid.stages.harmonic import pairing_orders

    tied = write_tied(tmp_path, [(1, 1, 1), (1, 2, 4), (1, 3, 5), (2, 1, 2), (2, 2, 3), (2, 3, 5)])
    out = pairing_orders([1, 0, 2, 0, 3, 0], tied)
    assert list(out) == ["chosen", "tied 1", "tied 2"]
    assert out["chosen"].tolist() == [1, 0, 2, 0, 3, 0]
    assert out["tied 1"].tolist() == [1, 0, 0, 2, 3, 0]
    assert out["tied 2"].tolist() == [0, 1, 2, 0, 3, 0]
    assert list(pairing_orders([1, 0, 2], None)) == ["chosen"]


def _range(k_off, paired):
    return {"damping_ratio_low": 0.02, "damping_ratio_high": 0.05, "damping_ratio_grid": [0.02, 0.035, 0.05],
            "k_min_N_per_m": [k_off * 2 / 3, k_off * 7 / 6, k_off * 5 / 3], "governing_fe_mode": [3, 3, 3],
            "k_min_low_N_per_m": k_off * 2 / 3, "k_min_high_N_per_m": k_off * 5 / 3,
            "paired": {name: {"k_paired_N_per_m": [v * 2 / 3, v * 7 / 6, v * 5 / 3], "k_paired_low_N_per_m": v * 2 / 3,
                              "k_paired_high_N_per_m": v * 5 / 3} for name, v in paired.items()}}


def _pairing_doc(state, k, rule):
    """Table 1's inputs of one state: FE mode 3 (the bounce) governs; the chosen pairing pairs it with
    measured mode 2, the tied one does not (its lowest paired peak is FE mode 5's, 1.5 k)."""
    ident = {"pairing": "chosen", "status": "identified", "governing_measured_order": 2,
             "paired_minimum": {"dynamic_stiffness_N_per_m": k, "fe_mode": 3, "measured_order": 2}}
    other = {"pairing": "tied 1", "governing_measured_order": None,
             "status": "not identified: the governing mode (FE mode 3, 1314.0 Hz, table bounce) has no measured partner",
             "paired_minimum": {"dynamic_stiffness_N_per_m": 1.5 * k, "fe_mode": 5, "measured_order": 3}}
    return {"state": state, "governing_mode": {"fe_mode": 3, "freq_Hz": 1314.0, "description": "table bounce",
                                               "damping_ratio": 0.03, "measured_order": 2},
            "status": "identified", "dynamic_stiffness_N_per_m": k, "static_stiffness_N_per_m": 4.0e8,
            "f_at_min_Hz": 1314.0, "paired_minimum": ident["paired_minimum"], "damping": {"config": {"model": "modal"}},
            "drive_point": "T05", "direction": "y", "patch_diameter_m": 0.01,
            "tie": {"rests_on_tie": True, "note": "an exactly tied pairing leaves ...", "rule": rule},
            "pairings": [ident, other], "damping_range": _range(k, {"chosen": k, "tied 1": 1.5 * k})}


def test_table1_reports_every_admissible_pairing_and_the_damping_range():
    from jointid.reporting.tables import table1_pairings_frame

    docs = [_pairing_doc("power_off", 6.0e7, "resolvability"), _pairing_doc("power_on", 7.2e7, "resolvability")]
    paper = pd.DataFrame({"state": ["power_off", "power_on"], "paper_dynamic_stiffness_N_per_mm": [104547.0, 148551.0]})
    df = table1_frame(docs, paper).set_index("state")
    assert df.loc["power_on", "tie_rule"] == "resolvability"
    assert df.loc["power_off", "k_dyn_min_low_N_per_mm"] == pytest.approx(4.0e4)  # 6e7 N/m * 2/3, in N/mm
    assert df.loc["power_off", "k_dyn_min_high_N_per_mm"] == pytest.approx(1.0e5)
    assert (df["damping_ratio_low"] == 0.02).all() and (df["damping_ratio_high"] == 0.05).all()
    assert df.loc["power_on", "increase_low_pct"] == pytest.approx(20.0)  # the same ratio in both states
    assert df.loc["power_on", "increase_high_pct"] == pytest.approx(20.0)
    assert df.loc["power_off", "governing_modes_over_damping_range"] == "3"
    pairs = table1_pairings_frame(docs)
    assert pairs[["state", "pairing"]].values.tolist() == [["power_off", "chosen"], ["power_off", "tied 1"],
                                                           ["power_on", "chosen"], ["power_on", "tied 1"]]
    assert pairs["k_dyn_min_N_per_mm"].tolist() == pytest.approx([6e4, 6e4, 7.2e4, 7.2e4])  # never only "—"
    assert pairs["status"].str.startswith("not identified").tolist() == [False, True, False, True]
    assert pairs["increase_pct"].iloc[2] == pytest.approx(20.0) and pairs["increase_pct"].isna().iloc[[0, 1, 3]].all()
    assert pairs["paired_k_dyn_high_N_per_mm"].tolist() == pytest.approx([1e5, 1.5e5, 1.2e5, 1.8e5])
    md = table1_markdown(table1_frame(docs, paper), None, pairs)
    assert "## Table 1 under every admissible pairing" in md
    assert "| power_off | tied 1 | not identified: the governing mode (FE mode 3" in md
    assert "The chosen pairing was chosen by: resolvability." in md
    assert "Over ζ 0.02–0.05 (the same ratio in both states): increase +20.0 … +20.0 %" in md


def _written(tmp_path, docs):
    from jointid.reporting.checks import TABLE1, TABLE1_PAIRINGS, TABLE1_RANGES
    from jointid.reporting.tables import RANGE_COLUMNS, table1_pairings_frame

    tmp_path.mkdir(parents=True, exist_ok=True)
    row = {c: 1.0 for c in RANGE_COLUMNS}
    row.update(state="power_on", reference_state="power_off", basis="paired modes", over="points", n_cases=18)
    pd.DataFrame([row]).to_csv(tmp_path / TABLE1_RANGES, index=False)
    table1_frame(docs, pd.DataFrame()).to_csv(tmp_path / TABLE1, index=False)
    table1_pairings_frame(docs).to_csv(tmp_path / TABLE1_PAIRINGS, index=False)
    return tmp_path


def test_the_table1_gate_reads_the_damping_range_and_every_pairing(tmp_path, capsys):
    from jointid.reporting.checks import TABLE1_PAIRINGS, check_table1

    docs = [_pairing_doc("power_off", 6.0e7, "resolvability"), _pairing_doc("power_on", 7.2e7, "resolvability")]
    folder = _written(tmp_path / "ok", docs)
    assert check_table1(folder) == []
    out = capsys.readouterr().out
    assert "power_off: band minimum 40,000–100,000 N/mm over damping ratio 0.02–0.05" in out
    assert "power_on under the tied 1 pairing: not identified: the governing mode (FE mode 3" in out
    # a damping range upside down fails
    bad = [dict(d, damping_range=dict(d["damping_range"], k_min_low_N_per_m=2e8)) for d in docs]
    assert any("k_dyn_min_low_N_per_mm 200000 > k_dyn_min_high_N_per_mm" in p for p in check_table1(_written(tmp_path / "r", bad)))
    # the chosen pairing's row must carry Table 1's status
    folder = _written(tmp_path / "p", docs)
    pairs = pd.read_csv(folder / TABLE1_PAIRINGS)
    pairs.loc[0, "status"] = pairs.loc[1, "status"]
    pairs.to_csv(folder / TABLE1_PAIRINGS, index=False)
    assert any("power_off: no single 'chosen' row with Table 1's status" in p for p in check_table1(folder))
