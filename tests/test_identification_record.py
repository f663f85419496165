"""The identification record (:mod:`jointid.identification.record`): params.json as a frozen dataclass.

The two files in tests/data/params were written by rule identify before the record existed (commit 626a00e):
``single_carriage_power_off.json`` (the second example: measured shapes, paired by MAC, joint damping, shape
rows in the polish) and ``coarse_power_on_surfaces.json`` (the coarse test run without the FE polish: frequency
pairing shared by the states, zoomed surfaces, a tie rule).  Read and written again, they keep every byte.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from jointid.identification.record import (FePolish, IdentificationRecord, Interval, Observability, PairedBy,
                                           PolishedOn, SurfaceStage, TieChoice, TieRule)

DATA = Path(__file__).parent / "data" / "params"
FILES = sorted(DATA.glob("*.json"))


def small_record() -> IdentificationRecord:
    """A record of every part, with numbers a run could give."""
    names = ["k_normal_N_per_m3", "k_feed_N_per_m3"]
    polish = FePolish(PolishedOn.FE, (1400.5,), ({"freq_Hz": 1400.5, "model_mode": 3},), 12.5, 4, 1.77, 3,
                      (0.1, 0.01), (344.5, 1314.8), (0.99, 0.98), None, 3.0, 10, 0.3, 0.02, 1.1)
    return IdentificationRecord(
        parameters={n: Interval(np.float64(v), np.float64(v / 2), np.float64(2 * v)) for n, v in zip(names, (1e12, 1e10))},
        state="power_off", surface_optimum={n: 1.5e11 for n in names}, surface_stage=SurfaceStage.ZOOM,
        surface_box={n: (1e11, 1e13) for n in names}, fe_polish=polish, edge_extrapolation={"passes": 2},
        per_carriage={"k_normal_per_carriage_N_per_um": Interval(np.float64(1234.5678901234567), 1000.0, 1500.0)},
        x_coded=(0.1, -0.2), pairing_tracked_mode=(1, 2), pairing_columns=(0, 1), paired_by=PairedBy.FREQUENCY_SHARED,
        joint_pairing={"candidates": [{"pairing": [0, 1], "cost": 0.1}]}, f_meas_Hz=(350.0, 1300.0),
        f_surface_Hz=(351.0, 1299.0), residual_pct=(-1.5, 1.1), cost=0.01, condition_number=2.5,
        weak_combination=None, on_bound=("k_feed_N_per_m3",), n_starts_agreeing=9, warnings=("a note",),
        frequency_uncertainty_pct=1.0, model_error={"c_hat": 12.5},
        tie_rule=TieRule("resolvability", ({"pairing": [0, 1], "resolvable": True},), {"power_off": "measured"}),
        observability=Observability(("T05:x",), ("T01:y",), "as given", (100.0, 3500.0), 0.25),
        joint_damping={"identified": False, "note": "no ratios"})


def test_round_trip_of_every_part():
    rec = small_record()
    assert IdentificationRecord.from_json(rec.to_json()) == rec
    assert IdentificationRecord.from_json(json.loads(json.dumps(rec.to_json()))) == rec


def test_write_read_write_keeps_the_bytes(tmp_path):
    rec = small_record()
    rec.write(tmp_path / "a.json")
    again = IdentificationRecord.read(tmp_path / "a.json")
    assert again == rec
    again.write(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_params_json_of_the_earlier_code_reads_back_byte_identical(path, tmp_path):
    rec = IdentificationRecord.read(path)
    assert IdentificationRecord.from_json(rec.to_json()) == rec
    rec.write(tmp_path / "params.json")
    assert (tmp_path / "params.json").read_bytes() == path.read_bytes()


def test_the_files_read_as_typed_parts():
    shapes = IdentificationRecord.read(DATA / "single_carriage_power_off.json")
    assert shapes.paired_by is PairedBy.MAC and not shapes.paired_by.by_frequency
    assert shapes.surface_stage is SurfaceStage.GLOBAL and shapes.fe_polish.on is PolishedOn.FE
    assert shapes.fe_polish.shape_dof > 0 and shapes.joint_damping["identified"] and shapes.tie_rule is None
    surfaces = IdentificationRecord.read(DATA / "coarse_power_on_surfaces.json")
    assert surfaces.paired_by is PairedBy.FREQUENCY_SHARED and surfaces.surface_stage is SurfaceStage.ZOOM
    assert surfaces.fe_polish is None and surfaces.model_error is None and surfaces.joint_damping is None
    assert surfaces.tie_rule.choice in set(TieChoice) and surfaces.pairing_candidates
    assert "joint_damping" not in surfaces.to_json()


def test_theta_and_intervals():
    rec = small_record()
    assert rec.names == ["k_normal_N_per_m3", "k_feed_N_per_m3"]
    assert rec.theta == {"k_normal_N_per_m3": 1e12, "k_feed_N_per_m3": 1e10}
    assert rec.theta_low["k_feed_N_per_m3"] == 5e9 and rec.theta_high["k_normal_N_per_m3"] == 2e12
    assert rec.interval("k_feed_N_per_m3") == Interval(1e10, 5e9, 2e10)


def test_tie_choice_reads_the_rule_text():
    assert TieRule("least cost (no tie)").choice is TieChoice.NO_TIE
    assert TieRule("resolvability").choice is TieChoice.RESOLVABILITY
    assert TieRule("nearest partners (fallback: no damping ratio to judge resolvability; 2 tied pairings)").choice \
        is TieChoice.NEAREST
    assert TieRule("something else").choice is None


def test_a_hand_written_document_reads_with_the_rest_empty():
    rec = IdentificationRecord.from_json({"parameters": {"k_N_per_m3": {"value": 1e12}}})
    assert rec.theta == {"k_N_per_m3": 1e12} and rec.interval("k_N_per_m3").ci95_low is None
    assert rec.paired_by is None and rec.fe_polish is None and rec.correction_record is None
