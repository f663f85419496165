"""The report's "what more of the test would add" section: one line per kind of data the dataset lacks."""

from __future__ import annotations

import pandas as pd

from jointid.identification.record import IdentificationRecord
from jointid.reporting.more_data import more_data_html, more_data_lines


def _data(paired_by="frequency, shared by all states", tied=True, damping=False, frf=None) -> dict:
    params = {s: IdentificationRecord.from_json(
        {"parameters": {}, "paired_by": paired_by,
         "tie_rule": {"rule": "resolvability", "tied": [{"pairing": [0, 1]}] if tied else []},
         **({"joint_damping": {"zeta_0": 0.01}} if damping else {})}) for s in ("power_off", "power_on")}
    table1 = pd.DataFrame({"state": ["power_off", "power_on"], "k_dyn_min_low_N_per_mm": [40918.2, 47386.0],
                           "k_dyn_min_high_N_per_mm": [97749.0, 112492.0], "damping_ratio_low": [0.02, 0.02],
                           "damping_ratio_high": [0.05, 0.05]})
    return {"params": params, "table1": table1, "frf_measured": frf}


def test_frequency_only_data_gets_three_lines_with_this_runs_numbers():
    lines = more_data_lines(_data())
    assert len(lines) == 3
    shapes, damping, frf = lines
    assert "MAC" in shapes and "power-off, power-on" in shapes and "tie rule" in shapes
    assert "power-off 40,918–97,749 N/mm over ζ 0.02–0.05" in damping
    assert "power-on 47,386–112,492 N/mm" in damping
    assert "FRAC" in frf and "drive-point" in frf
    html = more_data_html(_data())
    assert html.count("<li>") == 3 and "jointid data check" in html


def test_an_untied_frequency_pairing_says_so():
    assert "without a tie" in more_data_lines(_data(tied=False))[0]


def test_a_complete_dataset_gets_no_section():
    data = _data(paired_by="mac", damping=True, frf=({"power_off": None}, ["power_off"]))
    assert more_data_lines(data) == [] and more_data_html(data) == ""


def test_only_the_missing_kinds_are_listed():
    lines = more_data_lines(_data(paired_by="mac", frf=None))
    assert len(lines) == 2 and lines[0].startswith("<b>Damping ratios</b>")
