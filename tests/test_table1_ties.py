"""Table 1's status when it rests on the choice among exactly tied pairings (verify -> harmonic -> table1)."""

import numpy as np
import pandas as pd

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
    par = {"paired_by": "frequency, shared by all states", "pairing_columns": [0, 2, 4],
           "joint_pairing": {"candidates": CANDIDATES}}
    tied = tied_pairings(par, {"ref_shapes": ref.tolist()}, fe)
    assert list(tied.columns) == ["alternative", "order", "fe_mode"]
    assert tied[tied.alternative == 1].fe_mode.tolist() == [2, 5, 4]  # columns [0, 3, 4] -> FE 2, 5, 4 (1-based)
    assert tied[tied.alternative == 2].fe_mode.tolist() == [2, 1, 4]  # columns [0, 1, 4]
    # a one-state frequency pairing (re-paired at the FE optimum) has no tie record to read
    assert tied_pairings({**par, "paired_by": "frequency"}, {"ref_shapes": ref.tolist()}, fe).empty


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
    assert tie_note(empty, g=1, order=None, freq_Hz=1319.7) == {"rests_on_tie": False, "note": "", "tied_pairings": 0}
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
