"""Catalogue-style carriage rigidity (jointid.response.carriage) against closed-form limits."""

from __future__ import annotations

import copy
import json

import pytest

from conftest import REPO
from jointid.response.carriage import block_rig, block_rigidity
from jointid.config.options import CarriageOptions
from jointid.stages.carriage import run_carriage_rigidity
from jointid.config import load_config
from jointid.errors import ModelError
from jointid.config.typed import ModelSpec

THETA = {"k_normal_N_per_m3": 3.0e11, "k_lateral_N_per_m3": 1.3e12, "k_feed_N_per_m3": 8.4e9}
CELL_M = 0.008  # coarse: the tests check the mechanics, not the last digit


@pytest.fixture(scope="module")
def cfg():
    return load_config(REPO / "config.yaml")


def _spring_rigidity(cfg, theta):
    """Joint springs alone, N/m: parameter x contact area of one carriage (top w x L, flanks 2 h x L)."""
    r, c = cfg["rig"]["rails"], cfg["rig"]["carriages"]
    top, flanks = r["width_m"] * c["length_m"], 2 * c["flank_contact_height_m"] * c["length_m"]
    return {"normal": theta["k_normal_N_per_m3"] * top, "lateral": theta["k_lateral_N_per_m3"] * flanks,
            "feed": theta["k_feed_N_per_m3"] * (top + flanks)}


def test_with_rigid_parts_the_rigidity_is_that_of_the_springs(cfg):
    stiff = copy.deepcopy(cfg)
    for m in stiff["materials"].values():
        m["youngs_modulus_Pa"] *= 1e5
    got = block_rigidity(ModelSpec.from_config(stiff), THETA, CELL_M, parts=False).assembly_N_per_m
    want = _spring_rigidity(cfg, THETA)
    for d in want:
        assert got[d] == pytest.approx(want[d], rel=2e-4), d


def test_springs_and_parts_act_in_series(cfg):
    res = block_rigidity(ModelSpec.from_config(cfg), THETA, CELL_M)
    springs = _spring_rigidity(cfg, THETA)
    for d, a in res.assembly_N_per_m.items():
        p = res.parts_N_per_m[d]
        # softer than either alone; the plain series formula is only a guide (the joints' compliance
        # changes how the parts are loaded), but not far off
        assert a < springs[d] and a < p, d
        assert a == pytest.approx(1 / (1 / springs[d] + 1 / p), rel=0.2), d
    # the steel parts of the model are far stiffer than the joints normal to the rail top
    assert res.parts_N_per_m["normal"] > 10 * springs["normal"]


def test_each_spring_moves_its_own_direction(cfg):
    base = block_rigidity(ModelSpec.from_config(cfg), THETA, CELL_M, parts=False).assembly_N_per_m
    stiffer = block_rigidity(ModelSpec.from_config(cfg), {**THETA, "k_lateral_N_per_m3": 2 * THETA["k_lateral_N_per_m3"]}, CELL_M,
                             parts=False).assembly_N_per_m
    assert stiffer["lateral"] > 1.2 * base["lateral"]
    assert stiffer["normal"] == pytest.approx(base["normal"], rel=0.02)
    assert stiffer["feed"] == pytest.approx(base["feed"], rel=0.02)


def test_the_rigidity_converges_with_the_cell_size(cfg):
    coarse = block_rigidity(ModelSpec.from_config(cfg), THETA, 0.008).assembly_N_per_m
    fine = block_rigidity(ModelSpec.from_config(cfg), THETA, 0.006).assembly_N_per_m
    for d in coarse:
        assert coarse[d] == pytest.approx(fine[d], rel=0.01), d


def test_a_carriage_that_does_not_wrap_the_rail_is_refused(cfg):
    rig = copy.deepcopy(cfg["rig"])
    rig["carriages"]["width_m"] = rig["rails"]["width_m"]
    with pytest.raises(ModelError, match="must wrap the rail"):
        block_rig(rig)


def test_stage_writes_every_direction_with_an_interval(cfg, tmp_path):
    springs = _spring_rigidity(cfg, THETA)
    params = {"parameters": {n: {"value": v, "ci95_low": 0.8 * v, "ci95_high": 1.25 * v} for n, v in THETA.items()},
              "per_carriage": {"k_lateral_per_carriage_N_per_um": {"value": springs["lateral"] * 1e-6}}}
    (tmp_path / "params.json").write_text(json.dumps(params))
    run_cfg = copy.deepcopy(cfg)
    run_cfg["carriage_rigidity"]["cell_size_m"] = CELL_M
    doc = run_carriage_rigidity(CarriageOptions.from_config(run_cfg), "power_off", str(tmp_path / "params.json"), str(tmp_path / "out.json"),
                                log=lambda msg: None)
    written = json.loads((tmp_path / "out.json").read_text())
    assert written["state"] == "power_off" and set(written["directions"]) == {"lateral", "normal", "feed"}
    for d, r in written["directions"].items():
        assert r["assembly_N_per_um"] == pytest.approx(doc["directions"][d]["assembly_N_per_um"], rel=1e-9)
        assert r["assembly_ci95_low_N_per_um"] < r["assembly_N_per_um"] < r["assembly_ci95_high_N_per_um"], d
        assert 0 < r["joint_share_of_compliance"] < 1, d
    # the springs alone: the identification's per-carriage value, by the parameter's direction
    assert written["directions"]["lateral"]["joint_springs_N_per_um"] == pytest.approx(springs["lateral"] * 1e-6)
    assert written["directions"]["normal"]["joint_springs_N_per_um"] is None  # not in per_carriage here
