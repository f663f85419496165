"""End-to-end workflow on the coarse config: the job graph, a full run, and a failing stage.

The full run is the session fixture ``coarse_run`` (conftest.py), shared with the interruption,
determinism and rerun tests.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import (CORE_RULES, REPO, STATES, TABLE_COLUMNS, TABLES, clone_run, copy_workflow,
                      extra_rule_names, file_hashes, run_snakemake, scheduled_jobs, temporary_files,
                      write_config)
from jointid.config import load_config
from jointid.config.options import DoeOptions
from jointid.stages.doe import doe_sheet

pytestmark = pytest.mark.slow


def coarse_config() -> dict:
    overrides = yaml.safe_load((REPO / "tests" / "coarse_config.yaml").read_text())
    return load_config(REPO / "config.yaml", overrides=overrides)


def measured(state: str) -> pd.DataFrame:
    modes = pd.read_csv(REPO / "data" / "paper" / "modes.csv")
    return modes[modes.state == state].sort_values("mode")


def test_dry_run_lists_every_stage_once_per_state_and_the_doe_in_one_job(tmp_path):
    """solver.method reduced (the default): each DOE in one job; method full: one job per point."""
    wd = copy_workflow(tmp_path / "wf")
    proc = run_snakemake(wd, "-j2", "-n")
    assert proc.returncode == 0, proc.stderr
    jobs = scheduled_jobs(proc.stdout + proc.stderr)
    n_points = len(doe_sheet(DoeOptions.from_config(coarse_config())))
    assert n_points == 15 + 2  # face-centred CCF in 3 factors + 1 centre, 2 verification points
    expected = {"mesh": 1, "doe": 1, "modal": 1, "gather_modal": 1, "fit_surface": 1,
                "scout": len(STATES), "doe_zoom": 1, "modal_zoom": 1, "gather_zoom": 1, "fit_zoom": 1,
                "identify": len(STATES), "verify": len(STATES), "tables": 1}
    assert {r: n for r, n in jobs.items() if r in CORE_RULES} == expected
    (wd / "full.yaml").write_text("solver:\n  method: full\n")
    full = scheduled_jobs((lambda p: p.stdout + p.stderr)(run_snakemake(wd, "-j2", "-n", configs=[wd / "full.yaml"])))
    assert {r: full.get(r) for r in ("modal", "modal_zoom")} == {"modal": n_points, "modal_zoom": n_points}
    unknown = set(jobs) - set(CORE_RULES) - extra_rule_names(wd)
    assert not unknown, f"jobs of rules defined nowhere: {unknown}"
    # rule all also builds what the rule files append to EXTRA_TARGETS (report, diagnosis)
    # the mesh check and the carriage tests: one job for every state (the refined mesh, the test's mesh built once)
    extras = {"harmonic": len(STATES), "table1": 1, "report": 1, "diagnose": 1, "mesh_check": 1}
    assert {r: jobs.get(r, 0) for r in extras} == extras
    assert not (wd / "results").exists(), "a dry run must not write results"


def test_a_hypothesis_with_a_model_of_its_own_does_not_wait_for_the_mesh(tmp_path):
    """It builds its model from the configuration: neither the run's model file nor its basis is an input, so
    it can start beside rule mesh; one on the run's model (solver.method full: a job of its own) has both."""
    wd = copy_workflow(tmp_path / "wf")
    (wd / "own.yaml").write_text("hypotheses:\n  thin:\n    overrides: {rig: {table: {thickness_m: 0.030}}}\n"
                                 "  heavy:\n    overrides: {rig: {motors: {mass_each_kg: 6.0}}}\nsolver:\n  method: full\n")
    inputs = {}
    for name in ("thin", "heavy"):
        out = run_snakemake(wd, "-n", "-f", f"results/hypotheses/{name}/fit.json", configs=[wd / "own.yaml"],
                            check=True).stdout
        inputs[name] = re.search(r"^rule hypothesis:\n\s+input: (.*)$", out, flags=re.M).group(1)
    assert "matrices.npz" not in inputs["thin"] and "diagnosis_basis.npz" not in inputs["thin"], inputs
    assert "results/model/matrices.npz" in inputs["heavy"] and "diagnosis_basis.npz" in inputs["heavy"], inputs


def test_full_coarse_run_writes_both_tables(coarse_run):
    wd = coarse_run
    for path, state in zip(TABLES, STATES):
        tab = pd.read_csv(wd / path)
        assert list(tab.columns) == TABLE_COLUMNS, path
        meas = measured(state)
        assert len(tab) == len(meas), f"{path}: one row per measured mode"
        assert tab["order"].tolist() == list(range(1, len(meas) + 1))
        np.testing.assert_allclose(tab["experimental_Hz"], meas["freq_Hz"], rtol=1e-9)
        sim = tab["simulation_Hz"].to_numpy()
        assert np.all(np.isfinite(sim)) and np.all(sim > 0), f"{path}: every measured mode is paired"
        np.testing.assert_allclose(tab["relative_error_pct"],
                                   100 * (sim - tab["experimental_Hz"]) / tab["experimental_Hz"],
                                   rtol=1e-6, atol=1e-6)  # CSV keeps 10 digits
        # the coarse model is stiff and crude, but must land in the right range (not a pairing mix-up)
        assert np.abs(tab["relative_error_pct"]).max() < 50.0
        md = (wd / path).with_suffix(".md").read_text()
        assert md.count("\n|") >= len(meas) + 1, f"{path}: markdown table has one line per mode"


def test_tables_1_to_3_of_the_coarse_run_pass_the_ci_gates(coarse_run):
    """CI's gates (``python -m jointid.reporting.checks``) on the coarse run's tables: Tables 2 and 3
    within the paper's own errors (8.1 / 8.2 %, unpaired visible modes counted), Table 1 complete with
    a status per state and its ranges.  The default mesh's tables are what ``make reproduce`` gives."""
    from jointid.reporting.checks import check_frequency_tables, check_table1

    folder = coarse_run / "results" / "tables"
    assert check_frequency_tables(folder) == []
    assert check_table1(folder) == []


def test_full_coarse_run_params_within_bounds_and_clean(coarse_run):
    wd = coarse_run
    cfg = coarse_config()
    for state in STATES:
        par = json.loads((wd / "results" / "identify" / state / "params.json").read_text())
        assert par["state"] == state
        assert set(par["parameters"]) == set(cfg["joints"]["parameters"])
        for name, p in par["parameters"].items():
            b = cfg["joints"]["parameters"][name]
            assert b["lower"] * (1 - 1e-9) <= p["value"] <= b["upper"] * (1 + 1e-9), name
            assert p["ci95_low"] <= p["value"] <= p["ci95_high"], name
        verify = pd.read_csv(wd / "results" / "identify" / state / "verify.csv")
        assert len(verify) == len(measured(state))
    assert temporary_files(wd) == []
    for log in (wd / "logs").rglob("*.log"):
        assert "Traceback" not in log.read_text(), f"{log.name} holds a traceback"


def test_carriage_rigidity_of_each_state_is_softer_than_its_springs(coarse_run):
    for state in STATES:
        par = json.loads((coarse_run / f"results/identify/{state}/params.json").read_text())
        doc = json.loads((coarse_run / f"results/identify/{state}/carriage_rigidity.json").read_text())
        springs = {d: par["per_carriage"][f"k_{d}_per_carriage_N_per_um"]["value"] for d in doc["directions"]}
        for d, r in doc["directions"].items():
            assert r["joint_springs_N_per_um"] == pytest.approx(springs[d], rel=1e-9), (state, d)
            assert r["assembly_N_per_um"] < min(springs[d], r["parts_N_per_um"]), (state, d)
            assert r["assembly_ci95_low_N_per_um"] < r["assembly_N_per_um"] < r["assembly_ci95_high_N_per_um"]
    assert "Carriage rigidity" in (coarse_run / "results/report/index.html").read_text()


def test_identification_fits_mesh_extrapolated_frequencies(coarse_run):
    """mesh.extrapolate_edges (on by default): identify polishes again on the limits of the frequencies
    over the edge levels (the shipped config: 0 and +1 with mesh.edge_ratio given; the Aitken limit over
    0, +1, +2 is tested in tests/test_extrapolate.py), and verify fills the tables with those limits."""
    wd = coarse_run
    mesh = coarse_config()["mesh"]
    assert mesh["extrapolate_edges"] and mesh["edge_ratio"] == 0.45
    for state, table in zip(STATES, TABLES):
        par = json.loads((wd / "results" / "identify" / state / "params.json").read_text())
        edge = par["edge_extrapolation"]
        assert len(edge["n_dofs"]) == 2 and edge["n_dofs"][0] < edge["n_dofs"][1]  # one level solved, not two
        modes = pd.DataFrame(edge["modes"])
        assert "level2_Hz" not in modes
        ext = modes[modes.status == "extrapolated"]
        assert len(ext) >= len(modes) // 2
        # nested meshes: each level lowers a mode; the limit continues the geometric sequence of ratio r
        assert (ext.level1_Hz <= ext.level0_Hz * (1 + 1e-8)).all() and (ext.ratio == 0.45).all()
        np.testing.assert_allclose(ext.limit_Hz, ext.level1_Hz + (ext.level1_Hz - ext.level0_Hz) * 0.45 / 0.55,
                                   rtol=1e-9)
        ver = pd.read_csv(wd / "results" / "identify" / state / "verify.csv")
        assert (ver.simulation_Hz <= ver.simulation_mesh_Hz * (1 + 1e-8)).all()
        np.testing.assert_allclose(ver.simulation_Hz / ver.simulation_mesh_Hz, ver.edge_factor, rtol=1e-8)
        np.testing.assert_allclose(pd.read_csv(wd / table).simulation_Hz, ver.simulation_Hz, rtol=1e-8)
        # verify scales its full solve by the identification's recorded factors: the same frequencies as
        # the identification's last polish (on its certified reduced basis, 1e-6 in each eigenvalue)
        np.testing.assert_allclose(ver.simulation_Hz, par["fe_polish"]["f_fe_Hz"], rtol=1e-5)


def test_each_reported_optimum_carries_its_certificate(coarse_run):
    """identify's params.json holds the residual check of the polish's returned modes (reduced
    solver); verify's certificate.json the full solve's residual and Sturm count, with its sidecar."""
    import hashlib

    from jointid.reporting.provenance import provenance_path

    wd = coarse_run
    for state in STATES:
        par = json.loads((wd / "results" / "identify" / state / "params.json").read_text())
        polish = par["fe_polish"]["certificate"]
        assert polish["method"] in ("reduced", "full") and polish["passed"], (state, polish)
        assert polish["max_relative_residual"] <= polish["residual_tol"]
        assert (polish["method"] == "full") == (polish["fallback"] is not None)
        path = wd / "results" / "identify" / state / "certificate.json"
        doc = json.loads(path.read_text())
        assert doc["state"] == state and doc["identify"] == polish
        assert doc["parameters"] == pytest.approx({n: p["value"] for n, p in par["parameters"].items()}, rel=1e-11)
        ver = doc["verify"]
        assert ver["method"] == "full" and ver["passed"] and ver["complete"], (state, ver)
        assert ver["sturm_count"] == ver["n_modes_below_shift"] > 0 and ver["max_relative_residual"] <= 1e-6
        side = json.loads(provenance_path(path).read_text())
        assert side["table"] == path.name and side["table_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()


def test_zoomed_surfaces_are_more_accurate_and_carry_the_identification(coarse_run):
    """The second DOE sits in the box around the first-stage optima of both states; its surfaces
    agree with the FE model at its own fresh verification points better than the first ones do at
    theirs; the identification and the verification use them."""
    wd = coarse_run
    box = json.loads((wd / "results" / "doe" / "zoom" / "box.json").read_text())
    sheet = pd.read_csv(wd / "results" / "doe" / "zoom" / "points.csv")
    for j, name in enumerate(box["names"]):
        assert sheet[name].min() == pytest.approx(box["lower"][j], rel=1e-9)
        assert sheet[name].max() == pytest.approx(box["upper"][j], rel=1e-9)
        for state in STATES:
            scout = json.loads((wd / "results" / "identify" / state / "scout.json").read_text())
            assert box["lower"][j] < scout["surface_optimum"][name] * (1 + 1e-9)
            assert scout["surface_optimum"][name] < box["upper"][j] * (1 + 1e-9)
            assert scout["fe_polish"] is None  # the scout is the surfaces' optimum alone
    first = pd.read_csv(wd / "results" / "surface" / "diagnostics.csv")["verify_max_error_pct"]
    zoom = pd.read_csv(wd / "results" / "surface" / "zoom" / "diagnostics.csv")["verify_max_error_pct"]
    assert zoom.max() < first.max(), (zoom.max(), first.max())
    for state in STATES:
        par = json.loads((wd / "results" / "identify" / state / "params.json").read_text())
        assert par["surface_stage"] == "zoom"
        assert [par["surface_box"][n] for n in box["names"]] == [list(b) for b in zip(box["lower"], box["upper"])]


def test_mesh_check_takes_the_default_mesh_solve_from_verify(coarse_run, tmp_path, monkeypatch):
    """Rule verify keeps its solve at the identified parameters (``optimum_modes.npz``) and the mesh check
    reads it instead of solving the default mesh again: the check with that solve made afresh gives the
    same files, byte for byte."""
    from conftest import COARSE_RUN, coarse_config_dict
    from jointid.config import rule_keys as keys
    from jointid.config.options import MeshCheckOptions
    from jointid.config.snakefile import sections, validated
    from jointid.stages.meshcheck import run_mesh_check

    monkeypatch.chdir(coarse_run)
    cfg = validated(coarse_config_dict(COARSE_RUN), ["config.yaml"])
    opts = MeshCheckOptions.from_config(sections(cfg, *keys.MESH_CHECK))
    assert not opts.extrapolate  # the default: both meshes at their base level, verify's solve used
    state, r = STATES[0], coarse_run / "results"
    assert f"mesh_check[{state}]: default mesh at the identified parameters: rule verify's solve" in (
        coarse_run / "logs/mesh_check.log").read_text()  # one job for every state
    run_mesh_check(opts, state, str(r / f"identify/{state}/params.json"), str(r / f"identify/{state}/verify.csv"),
                   str(r / "model/matrices.npz"), str(tmp_path / "check.json"), str(tmp_path / "check.csv"),
                   log=lambda m: None)
    assert (tmp_path / "check.json").read_bytes() == (r / f"mesh_check/{state}.json").read_bytes()
    assert (tmp_path / "check.csv").read_bytes() == (r / f"mesh_check/{state}.csv").read_bytes()


def test_mesh_check_reports_a_nested_refinement_of_each_state(coarse_run):
    wd = coarse_run
    cfg = coarse_config()
    for state in STATES:
        doc = json.loads((wd / f"results/mesh_check/{state}.json").read_text())
        par = json.loads((wd / f"results/identify/{state}/params.json").read_text())
        assert doc["n_dofs_refined"] > 1.5 * doc["n_dofs_default"]  # cells halved through the thickness
        assert set(doc["parameters"]) == set(par["parameters"])
        for name, p in doc["parameters"].items():
            # JSON files keep 12 significant digits (jointid.io.write_json)
            assert p["value"] == pytest.approx(par["parameters"][name]["value"], rel=1e-10)
            assert np.isfinite(p["change_pct"]) and p["ci95_half_width_pct"] > 0
            big = abs(p["change_pct"]) > doc["max_parameter_change_pct"]
            assert big == any(w.startswith(f"{name} would change") for w in doc["warnings"])
        tab = pd.read_csv(wd / f"results/mesh_check/{state}.csv")
        ok = tab.dropna()
        # nested meshes: no frequency can rise (min-max principle), and each paired mode follows by MAC;
        # with mesh.extrapolate_edges (the default) the meshes' own frequencies stand beside the limits
        assert doc["extrapolated_over_edge_levels"] is (cfg["mesh"]["extrapolate_edges"]
                                                        and cfg["mesh_check"].get("edge_levels", False))
        # the budget: each paired mode's change against a third of sqrt(noise^2 + model error^2)
        b = doc["budget"]
        me = par["model_error"]
        assert b["uncertainty_pct"] == pytest.approx(np.hypot(par["frequency_uncertainty_pct"], me["sigma_model_pct"]))
        assert b["budget_pct"] == pytest.approx(b["uncertainty_pct"] * cfg["mesh_check"]["budget_fraction"])
        assert b["within"] is (b["max_error_pct"] <= b["budget_pct"])
        # a refinement of fewer than the three axes says that a uniform one would find more
        from jointid.geometry.mesh import axes_halved
        covered = all(axes_halved(tuple(doc["halved"])))
        assert ("part of a uniform refinement's error" in b["sentence"]) is not covered
        paired = tab[tab.measured_mode > 0].sort_values("measured_mode")
        np.testing.assert_allclose(b["error_pct"], paired.change_pct.abs(), rtol=1e-6)
        own = ("default_mesh_Hz", "refined_mesh_Hz") if doc["extrapolated_over_edge_levels"] else ("default_Hz", "refined_Hz")
        assert (ok[own[1]] <= ok[own[0]] * (1 + 1e-8)).all()
        assert (ok.mac >= 0.8).all()
        assert sorted(tab.measured_mode[tab.measured_mode > 0]) == list(range(1, len(par["f_meas_Hz"]) + 1))


def test_failing_stage_leaves_no_partial_output_and_keeps_earlier_results(coarse_run, tmp_path):
    wd = clone_run(coarse_run, tmp_path / "wf")
    bad = wd / "data" / "bad"
    bad.mkdir()
    (bad / "conditions.yaml").write_text((wd / "data" / "paper" / "conditions.yaml").read_text())
    (bad / "modes.csv").write_text((wd / "data" / "paper" / "modes.csv").read_text())
    # a shape at a point the model does not have: only a stage that knows the model's measuring points
    # can tell (everything else is checked before the first job), so the run fails mid-way
    (bad / "shapes.csv").write_text("state,mode,point,direction,value\npower_off,1,T99,y,1.0\n")
    override = write_config(wd / "bad_dataset.yaml", "measurements:\n  dataset: data/bad\n")

    upstream = ("results/model/*", "results/doe/*", "results/modal/**/*", "results/surface/*")
    # (the shared diagnosis basis reads the measured dataset: its job fails on it too and leaves nothing)
    before = {k: v for k, v in file_hashes(wd, upstream).items() if not k.endswith("diagnosis_basis.npz")}
    mtimes = {p: (wd / p).stat().st_mtime_ns for p in before}
    downstream_before = file_hashes(wd, ("results/tables/*",))

    proc = run_snakemake(wd, "-j2", "--keep-going", configs=[override])
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Error in rule scout" in out  # the first stage that reads the measured frequencies
    for state in STATES:
        assert not (wd / "results" / "identify" / state / "scout.json").exists(), \
            f"{state}: the failed scout must not leave scout.json"
        log = (wd / "logs" / "scout" / f"{state}.log").read_text()
        assert "Traceback" not in log, "a DataError is reported without a traceback"
        assert "data/bad/shapes.csv:2" in log and "T99" in log, log
    # earlier results untouched (bytes and times), no stray temporary files
    assert not (wd / "results" / "model" / "diagnosis_basis.npz").exists()  # its job failed: nothing left
    assert "T99" in (wd / "logs" / "diagnosis_basis.log").read_text()
    assert {k: v for k, v in file_hashes(wd, upstream).items() if not k.endswith("diagnosis_basis.npz")} == before
    assert {p: (wd / p).stat().st_mtime_ns for p in before} == mtimes
    assert file_hashes(wd, ("results/tables/*",)) == downstream_before
    assert temporary_files(wd / "results") == []
