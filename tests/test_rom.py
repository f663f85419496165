"""Reduced-order model against full modal solves of the coarse rig model, and the ROM as the
``solver.method: rom`` option of the workflow's modal stage (stages.run_rom / run_modal, rule rom)."""

import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import copy_workflow, scheduled_jobs, snakemake_cmd, tail, workflow_env, write_config
from jointid import io
from jointid.config import load_config
from jointid.identification.doe import to_physical
from jointid.errors import ConfigError, ModelError, NumericalWarning
from jointid.correlate.mac import mac
from jointid.fe.modal import solve_modes
from jointid.fe.model import base_coefficients, build_model, save_model
from jointid.identification.rom import ROM, frequency_error, load_rom
from jointid.identification.rom_build import RomOptions, build_rom, residual_indicator, training_points
from jointid.identification.polish import PolishFit, polish_on_model
from jointid.config.options import DoeOptions
from jointid.stages.doe import doe_sheet
from jointid.stages.modal import run_modal, run_rom
from jointid.config.typed import ModelSpec

ROOT = Path(__file__).resolve().parents[1]
TOL = 1e-4
N_MODES = 8  # tracked modes (the workflow tracks 12-20; 8 keeps this file fast)


def _cfg(solver=None, **mesh):
    over = yaml.safe_load((ROOT / "tests" / "coarse_config.yaml").read_text())
    over["mesh"].update(mesh)
    over["solver"]["backend"] = "scipy"  # SuperLU is the faster backend at these sizes
    over["solver"].update(solver or {})
    return load_config(ROOT / "config.yaml", overrides=over)


def _random_thetas(cfg, n, seed):
    names = list(cfg["joints"]["parameters"])
    lo = [cfg["joints"]["parameters"][k]["lower"] for k in names]
    hi = [cfg["joints"]["parameters"][k]["upper"] for k in names]
    X = np.random.default_rng(seed).uniform(-0.95, 0.95, size=(n, len(names)))
    return [dict(zip(names, row)) for row in to_physical(X, lo, hi).tolist()]


def _full(model, cfg, theta, n=N_MODES):
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, theta)
    modes = solve_modes(model.K(kc), model.M(mc), n, shift_Hz=cfg["solver"]["shift_Hz"], fixed=model.fixed,
                        backend="scipy")
    return modes.freqs_Hz, model.probe @ modes.phi, kc, mc


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    """The workflow's rom stage on the coarse model: ``(cfg, model, folder, sheet, summary)``; the
    folder holds matrices.npz, points.csv (the DOE sheet), rom.npz and rom.json."""
    cfg = _cfg(solver={"n_modes": N_MODES, "method": "rom"})
    folder = tmp_path_factory.mktemp("rom_stage")
    model = build_model(ModelSpec.from_config(cfg))
    save_model(model, folder / "matrices.npz")
    sheet = doe_sheet(DoeOptions.from_config(cfg))
    io.write_csv(sheet, folder / "points.csv")
    summary = run_rom(ModelSpec.from_config(cfg), str(folder / "matrices.npz"), str(folder / "points.csv"), str(folder / "rom.npz"),
                      str(folder / "rom.json"))
    return cfg, model, folder, sheet, summary


@pytest.fixture(scope="module")
def coarse(stage):
    """``(cfg, model, rom)``: the ROM the rom stage wrote (centre solve, inverse iterations at the
    corners, greedy-verified)."""
    cfg, model, folder, _, _ = stage
    return cfg, model, load_rom(folder / "rom.npz")


def test_rom_matches_full_solve_at_random_interior_points(coarse):
    cfg, model, rom = coarse
    assert rom.report["verified"] and rom.report["max_error"] <= TOL
    assert rom.size < 20 * N_MODES  # a real reduction: r << n_dofs
    for theta in _random_thetas(cfg, 2, seed=11):
        f_full, sh_full, kc, mc = _full(model, cfg, theta)
        f_rom, sh_rom = rom.solve(kc, mc)
        err = frequency_error(f_rom, f_full)
        assert np.max(err) <= TOL, (theta, err)
        # Rayleigh-Ritz: reduced frequencies bound the full ones from above
        assert np.all(f_rom >= f_full * (1 - 1e-9))
        m = np.diag(mac(sh_rom, sh_full))
        assert m.min() > 0.999, m
        # same result through joint parameters
        f2, _ = rom.solve_theta(theta)
        np.testing.assert_allclose(f2, f_rom, rtol=1e-12)


def test_rom_shapes_are_mass_normalised_full_vectors(coarse):
    cfg, model, rom = coarse
    kc, mc = rom.coefficients({})
    f, shapes, y = rom.solve(kc, mc, return_coords=True)
    phi = rom.expand(y)
    M, K = model.M(mc), model.K(kc)
    np.testing.assert_allclose(phi.T @ (M @ phi), np.eye(N_MODES), atol=1e-8)
    np.testing.assert_allclose(np.diag(phi.T @ (K @ phi)), (2 * np.pi * f) ** 2, rtol=1e-8)
    np.testing.assert_allclose(model.probe @ phi, shapes, atol=1e-12)
    assert np.all(phi[model.fixed] == 0.0)


def test_coefficients_match_base_coefficients(coarse):
    cfg, model, rom = coarse
    theta = _random_thetas(cfg, 1, seed=5)[0]
    kc, mc = rom.coefficients(theta)
    kb, mb = base_coefficients(ModelSpec.from_config(cfg), model, theta)
    assert set(kc) == set(kb) and mc == mb
    for k in kb:
        assert kc[k] == pytest.approx(kb[k], rel=1e-12)


def test_save_load_roundtrip(coarse, tmp_path):
    cfg, model, rom = coarse
    theta = _random_thetas(cfg, 1, seed=9)[0]
    kc, mc = rom.coefficients(theta)
    path = tmp_path / "rom.npz"
    rom.save(path, include_basis=False)
    back = ROM.load(path)
    assert back.basis is None and back.size == rom.size and back.report["verified"]
    assert back.coefficients(theta) == (kc, mc) and back.coeff_range == rom.coeff_range
    f1, s1 = rom.solve(kc, mc)
    f2, s2 = back.solve(kc, mc)
    np.testing.assert_array_equal(f1, f2)
    np.testing.assert_array_equal(s1, s2)
    with pytest.raises(ModelError, match="basis was not stored"):
        back.expand(np.zeros((back.size, 1)))
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ModelError, match="not a readable ROM"):
        ROM.load(bad)


def test_guards(coarse):
    cfg, model, rom = coarse
    kc, mc = rom.coefficients({})
    with pytest.raises(ModelError, match="K_nonexistent"):
        rom.solve({**kc, "K_nonexistent": 1.0}, mc)
    with pytest.raises(ModelError, match="unknown"):
        rom.coefficients({"k_twist_N_per_m3": 1.0})
    hi = {k: 10 * v for k, v in kc.items()}
    with pytest.warns(NumericalWarning, match="outside the verified"):
        rom.solve(hi, mc)


def test_training_points_corners_and_star():
    c = training_points(3, "corners")
    assert c.shape == (9, 3) and np.all(c[0] == 0) and np.all(np.abs(c[1:]) == 1)
    assert len({tuple(r) for r in c}) == 9
    s = training_points(3, "star")
    assert s.shape == (7, 3) and np.all(np.abs(s[1:]).sum(axis=1) == 1)
    with pytest.raises(ModelError):
        training_points(2, "sobol")


def test_greedy_enrichment_reaches_tolerance():
    """From the centre point alone the ROM is poor; greedy enrichment at the candidates with the
    largest residual indicator repairs it, and the result holds at independent random points."""
    cfg = _cfg(element="hex1")  # cheap model: this test exercises the error-control loop
    spec = ModelSpec.from_config(cfg)
    model = build_model(spec)
    with pytest.warns(NumericalWarning, match="still above"):
        poor = build_rom(model, spec, [np.zeros(3)], RomOptions(6, n_extra=0, n_verify=2, max_rounds=1, seed=1))
    assert poor.report["max_error"] > TOL and not poor.report["verified"]
    rom = build_rom(model, spec, [np.zeros(3)], RomOptions(6, n_extra=0, n_verify=2, max_rounds=8, seed=1))
    rounds = rom.report["rounds"]
    assert len(rounds) >= 2 and rounds[0]["max_error"] > TOL
    assert rom.report["verified"] and rounds[-1]["max_error"] <= TOL
    assert rom.size > poor.size
    for theta in _random_thetas(cfg, 4, seed=21):
        f_full, _, kc, mc = _full(model, cfg, theta, 6)
        f_rom, _ = rom.solve(kc, mc)
        assert np.max(frequency_error(f_rom, f_full)) <= TOL


def test_residual_indicator_vanishes_at_a_training_point(coarse):
    """At the fully solved training point (the centre) the ROM contains the exact modes: residual at
    round-off level there, clearly larger in the interior."""
    cfg, model, rom = coarse
    assert rom.report["training"][0]["how"] == "full solve"
    kc, mc = rom.coefficients(rom.report["training"][0]["theta"])  # the centre
    eta_corner = residual_indicator(model, rom, kc, mc)
    kc, mc = rom.coefficients(_random_thetas(cfg, 1, seed=4)[0])
    eta_inside = residual_indicator(model, rom, kc, mc)
    assert eta_corner.shape == (N_MODES,)
    assert eta_corner.max() < 1e-6 and eta_inside.max() > 10 * eta_corner.max()


def test_frequencies_only_path_matches_solve(coarse):
    cfg, model, rom = coarse
    kc, mc = rom.coefficients(_random_thetas(cfg, 1, seed=13)[0])
    f, _ = rom.solve(kc, mc)
    np.testing.assert_allclose(rom.frequencies(kc, mc), f, rtol=1e-10)
    # a different mass (generalised problem) agrees with the full solve's trend and with solve()
    mc2 = {**mc, "M_motor": 1.5 * mc["M_motor"]}
    with pytest.warns(NumericalWarning):
        f2, _ = rom.solve(kc, mc2)
    np.testing.assert_allclose(rom.frequencies(kc, mc2, check=False), f2, rtol=1e-10)
    assert np.all(f2 <= f * (1 + 1e-12)) and np.any(f2 < f * (1 - 1e-4))  # more mass, lower frequencies


# ------------------------------------------------------------------ solver.method: rom in the workflow
def _theta(cfg, sheet, point):
    row = sheet.set_index("point").loc[point]
    return {n: float(row[n]) for n in cfg["joints"]["parameters"]}


def test_rom_stage_meets_the_tolerance_and_reports_it(stage):
    cfg, model, folder, sheet, summary = stage
    doc = json.loads((folder / "rom.json").read_text())  # floats written to 12 digits
    assert set(doc) == set(summary) and doc["verified"] is True
    assert doc["max_error"] == pytest.approx(summary["max_error"], rel=1e-10)
    assert doc["basis_size"] == summary["basis_size"] and len(doc["rounds"]) == len(summary["rounds"])
    assert summary["tolerance"] == cfg["solver"]["rom_tolerance"] == TOL
    assert summary["verified"] and 0.0 <= summary["max_error"] <= TOL
    assert summary["rounds"] and summary["rounds"][-1]["max_error"] == summary["max_error"]
    assert summary["n_doe_candidates"] == len(sheet) and summary["n_dofs"] == model.n_dofs
    # the centre solved in full, the 2^3 corners by inverse iteration, then the verification solves
    assert summary["n_inverse_iteration_points"] == 8
    assert summary["n_full_solves"] == 1 + sum(len(r["points"]) for r in summary["rounds"])
    rom = load_rom(folder / "rom.npz")
    assert rom.basis is not None and rom.basis.shape == (model.n_dofs, summary["basis_size"])


@pytest.mark.parametrize("role", ["design", "verify"])
def test_rom_modal_output_equals_the_full_modal_output(stage, tmp_path, role):
    """At a DOE point that is not a training point (a face centre of the CCF; a random verification
    point), the rom path writes the full path's arrays: same names, types, labels and theta,
    frequencies within the tolerance (and above the full ones: Rayleigh-Ritz), MAC >= 0.999, the
    same mode descriptions."""
    cfg, model, folder, sheet, _ = stage
    x = sheet[[c for c in sheet.columns if c.startswith("x_")]].abs()
    pick = sheet[(sheet.role == role) & ((x.sum(axis=1) == 1.0) if role == "design" else True)]
    point = pick.point.iloc[0]
    theta = _theta(cfg, sheet, point)
    full_cfg = {**cfg, "solver": {k: v for k, v in cfg["solver"].items() if k not in ("method", "rom_tolerance")}}
    run_modal(ModelSpec.from_config(full_cfg), str(folder / "matrices.npz"), theta, str(tmp_path / "full.npz"))
    run_modal(ModelSpec.from_config(cfg), str(folder / "matrices.npz"), theta, str(tmp_path / "rom.npz"), rom=str(folder / "rom.npz"))
    full, red = np.load(tmp_path / "full.npz"), np.load(tmp_path / "rom.npz")
    assert sorted(red.files) == sorted(full.files)
    for key in full.files:
        assert red[key].dtype.kind == full[key].dtype.kind and red[key].shape == full[key].shape, key
    for key in ("labels", "theta_names", "theta"):
        np.testing.assert_array_equal(red[key], full[key])
    f_full, f_rom = full["freqs_Hz"], red["freqs_Hz"]
    assert len(f_full) == N_MODES
    tracked = f_full >= cfg["solver"]["min_freq_Hz"]
    assert tracked.sum() >= N_MODES - 1
    err = frequency_error(f_rom, f_full)[tracked]
    assert err.max() <= TOL, (point, err)
    assert np.all(f_rom >= f_full * (1 - 1e-9))
    m = np.diag(mac(red["shapes"], full["shapes"]))[tracked]
    assert m.min() >= 0.999, (point, m)
    np.testing.assert_array_equal(red["description"], full["description"])
    np.testing.assert_allclose(red["strain_joints"], full["strain_joints"], atol=1e-3)


def test_rom_method_without_the_rom_file_is_a_clear_error(stage, tmp_path):
    cfg, _, folder, sheet, _ = stage
    with pytest.raises(ConfigError, match="solver.method: rom needs the reduced-order model"):
        run_modal(ModelSpec.from_config(cfg), str(folder / "matrices.npz"), _theta(cfg, sheet, "d000"),
                  str(tmp_path / "x.npz"))
    assert not (tmp_path / "x.npz").exists()


def _modal_inputs(output: str) -> list[str]:
    """The ``input:`` line of every modal job of a dry-run's output."""
    return re.findall(r"^rule modal:\n\s+input: (.*)$", output, flags=re.M)


def test_dry_run_rom_rule_once_with_method_rom_and_never_with_full(tmp_path):
    """Coarse dry-runs: with solver.method: rom one rom job that every modal job takes as input;
    with full no rom job and modal jobs exactly as before the option existed."""
    runs = {}
    for method in ("full", "rom"):
        wd = copy_workflow(tmp_path / method)
        extra = [write_config(tmp_path / f"{method}.yaml", f"solver:\n  method: {method}\n")]
        runs[method] = subprocess.Popen(snakemake_cmd("-n", "-j2", configs=extra), cwd=wd, env=workflow_env(),
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = {m: p.communicate(timeout=300)[0] for m, p in runs.items()}  # the two run side by side
    for m, p in runs.items():
        assert p.returncode == 0, tail(out[m])
    n_points = len(doe_sheet(DoeOptions.from_config(_cfg())))
    jobs = {m: scheduled_jobs(text) for m, text in out.items()}
    assert jobs["rom"]["rom"] == 1 and jobs["rom"]["modal"] == n_points
    assert "rom" not in jobs["full"] and jobs["full"]["modal"] == n_points
    assert {r: n for r, n in jobs["rom"].items() if r != "rom"} == jobs["full"]
    rom_inputs, full_inputs = _modal_inputs(out["rom"]), _modal_inputs(out["full"])
    assert len(rom_inputs) == len(full_inputs) == n_points
    assert all("results/rom/rom.npz" in line.split(", ") for line in rom_inputs)
    assert all(line == "results/model/matrices.npz, results/doe/points.csv" for line in full_inputs)
    # the identify jobs polish on the ROM with method rom, on the FE model otherwise
    ident = {m: re.findall(r"^rule identify:\n\s+input: (.*)$", text, flags=re.M) for m, text in out.items()}
    assert len(ident["rom"]) == len(ident["full"]) == 2
    assert all("results/rom/rom.npz" in line for line in ident["rom"])
    assert not any("rom.npz" in line for line in ident["full"])
    assert re.search(r"^rule rom:\n\s+input: results/model/matrices.npz, results/doe/points.csv\n"
                     r"\s+output: results/rom/rom.npz, results/rom/rom.json", out["rom"], flags=re.M)


@pytest.mark.extended  # the second training kind of the ROM, which is not the default solver (the first: the tests above)
def test_training_kind_is_checked_and_modes_training_still_verifies(coarse):
    """Both training kinds meet the tolerance at fresh interior points; a wrong kind is a clear error."""
    cfg, model, rom_inverse = coarse
    with pytest.raises(ModelError, match="training 'lanczos' is unknown"):
        build_rom(model, ModelSpec.from_config(cfg), "corners", RomOptions(N_MODES, training="lanczos"))
    rom_modes = build_rom(model, ModelSpec.from_config(cfg), "corners",
                          RomOptions(N_MODES, training="modes", tol=TOL, seed=3))
    assert rom_modes.report["verified"]
    assert [t["how"] for t in rom_inverse.report["training"]][1:] == ["1 inverse iteration(s)"] * 8
    for theta in _random_thetas(cfg, 2, seed=21):
        f_full, _, kc, mc = _full(model, cfg, theta)
        for rom in (rom_inverse, rom_modes):
            assert np.max(frequency_error(rom.solve(kc, mc)[0], f_full)) <= TOL


def _polish_case(cfg, model):
    """A known truth for the polish tests: names, bounds, true parameters, its full-solve frequencies
    and shapes, and the first five modes above solver.min_freq_Hz."""
    names = list(cfg["joints"]["parameters"])
    lo = np.array([cfg["joints"]["parameters"][n]["lower"] for n in names])
    hi = np.array([cfg["joints"]["parameters"][n]["upper"] for n in names])
    truth = _random_thetas(cfg, 1, seed=17)[0]
    f_full, shapes, _, _ = _full(model, cfg, truth)
    keep = np.flatnonzero(f_full >= cfg["solver"]["min_freq_Hz"])[:5]
    return names, lo, hi, np.array([truth[n] for n in names]), f_full, shapes, keep


def test_polish_on_the_rom_recovers_the_full_model_truth(coarse):
    """Gauss-Newton polish on the ROM (the identify stage with solver.method: rom) lands where the
    full-model polish lands: frequencies synthesised by a full solve at a known truth are recovered."""
    cfg, model, rom = coarse
    names, lo, hi, theta_true, f_full, shapes, keep = _polish_case(cfg, model)
    theta0 = theta_true * np.array([1.3, 0.75, 1.2])
    results = {}
    for kind, m in (("rom", rom), ("full", model)):
        res = polish_on_model(ModelSpec.from_config(cfg), m, names, theta0,
                              PolishFit(f_full[keep], shapes[:, keep], lo, hi, sigma_rel=0.01), log=lambda msg: None)
        results[kind] = np.asarray(res["theta"])
        np.testing.assert_allclose(res["f_fe"], f_full[keep], rtol=5 * TOL)
    np.testing.assert_allclose(results["rom"], theta_true, rtol=0.01)
    np.testing.assert_allclose(results["rom"], results["full"], rtol=0.01)


def test_polish_reports_model_modes_left_unpaired_inside_the_measured_band(coarse):
    """A measured set that misses one mode in the middle of its band: the polish names that model
    mode (and only it) as unpaired in band — the identify stage warns with it."""
    cfg, model, rom = coarse
    names, lo, hi, theta_true, f_full, shapes, keep = _polish_case(cfg, model)
    seen = keep[[0, 1, 3, 4]]
    spec = ModelSpec.from_config(cfg)
    res = polish_on_model(spec, rom, names, theta_true, PolishFit(f_full[seen], shapes[:, seen], lo, hi),
                          log=lambda m: None)
    assert res["unpaired_in_band_Hz"] == pytest.approx([f_full[keep[2]]], rel=5 * TOL)
    full = polish_on_model(spec, rom, names, theta_true, PolishFit(f_full[keep], shapes[:, keep], lo, hi),
                           log=lambda m: None)
    assert full["unpaired_in_band_Hz"] == []
