"""The whole identification on a mesh file: the rig exported with its named groups and read back
through ``model: {kind: mesh}`` identifies the same joint parameters on the paper's data as the
parametric rig itself (coarse mesh, no edge extrapolation: a mesh file is solved as it is), with the
same pairing of measured and model modes.  The zoomed second DOE is on: there the paper's data hold
pairings of equal fit, and which of them a multistart finds first follows the round-off of the DOF
numbering; the pairing must not."""

from __future__ import annotations

import json

import pytest
import yaml

from conftest import coarse_config_dict, copy_workflow, run_snakemake, write_config
from jointid.config.load import load_config
from jointid.fe.meshexport import export_rig
from jointid.config.typed import ModelSpec

pytestmark = [pytest.mark.slow, pytest.mark.extended]

SAME_RUN = "mesh: {extrapolate_edges: false}\nmesh_check: {enabled: false}\n"
TARGETS = ("results/identify/power_off/params.json", "results/identify/power_on/params.json")


def test_rig_read_back_from_a_mesh_file_identifies_the_same_parameters(tmp_path):
    rig_dir, mesh_dir = copy_workflow(tmp_path / "rig"), copy_workflow(tmp_path / "mesh")
    cfg = load_config(coarse_config_dict(), overrides=yaml.safe_load(SAME_RUN))
    (mesh_dir / "own").mkdir()
    section = export_rig(ModelSpec.from_config(cfg), mesh_dir / "own" / "rig.msh", mesh_dir / "own" / "points.csv")
    section.update(path="own/rig.msh", points="own/points.csv")  # relative to the working directory
    same = write_config(tmp_path / "same.yaml", SAME_RUN)
    as_mesh = write_config(tmp_path / "as_mesh.yaml", SAME_RUN + yaml.safe_dump({"model": section}))
    run_snakemake(rig_dir, "-j2", *TARGETS, configs=[same], check=True)
    run_snakemake(mesh_dir, "-j2", *TARGETS, configs=[as_mesh], check=True)
    for target in TARGETS:
        ra, rb = (json.loads((d / target).read_text()) for d in (rig_dir, mesh_dir))
        assert ra["pairing_columns"] == rb["pairing_columns"], target
        a, b = ra["parameters"], rb["parameters"]
        assert set(a) == set(b) == {"k_normal_N_per_m3", "k_lateral_N_per_m3", "k_feed_N_per_m3"}
        for name in a:
            assert b[name]["value"] == pytest.approx(a[name]["value"], rel=1e-6), (target, name)
