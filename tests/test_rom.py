"""Reduced-order model against full modal solves of the coarse rig model."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from jointid.config import load_config
from jointid.doe import to_physical
from jointid.errors import ModelError, NumericalWarning
from jointid.modal import mac, solve_modes
from jointid.model import base_coefficients, build_model
from jointid.rom import ROM, build_rom, frequency_error, residual_indicator, training_points

ROOT = Path(__file__).resolve().parents[1]
TOL = 1e-4
N_MODES = 8  # tracked modes (the workflow tracks 12-20; 8 keeps this file fast)


def _cfg(**mesh):
    over = yaml.safe_load((ROOT / "tests" / "coarse_config.yaml").read_text())
    over["mesh"].update(mesh)
    over["solver"]["backend"] = "scipy"  # SuperLU is the faster backend at these sizes
    return load_config(ROOT / "config.yaml", overrides=over)


def _random_thetas(cfg, n, seed):
    names = list(cfg["joints"]["parameters"])
    lo = [cfg["joints"]["parameters"][k]["lower"] for k in names]
    hi = [cfg["joints"]["parameters"][k]["upper"] for k in names]
    X = np.random.default_rng(seed).uniform(-0.95, 0.95, size=(n, len(names)))
    return [dict(zip(names, row)) for row in to_physical(X, lo, hi).tolist()]


def _full(model, cfg, theta, n=N_MODES):
    kc, mc = base_coefficients(cfg, model, theta)
    modes = solve_modes(model.K(kc), model.M(mc), n, shift_Hz=cfg["solver"]["shift_Hz"], fixed=model.fixed,
                        backend="scipy")
    return modes.freqs_Hz, model.probe @ modes.phi, kc, mc


@pytest.fixture(scope="module")
def coarse():
    cfg = _cfg()
    model = build_model(cfg)
    rom = build_rom(model, cfg, N_MODES, "corners", n_verify=1, seed=3)
    return cfg, model, rom


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
    kb, mb = base_coefficients(cfg, model, theta)
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
    model = build_model(cfg)
    with pytest.warns(NumericalWarning, match="still above"):
        poor = build_rom(model, cfg, 6, [np.zeros(3)], n_extra=0, n_verify=2, max_rounds=1, seed=1)
    assert poor.report["max_error"] > TOL and not poor.report["verified"]
    rom = build_rom(model, cfg, 6, [np.zeros(3)], n_extra=0, n_verify=2, max_rounds=8, seed=1)
    rounds = rom.report["rounds"]
    assert len(rounds) >= 2 and rounds[0]["max_error"] > TOL
    assert rom.report["verified"] and rounds[-1]["max_error"] <= TOL
    assert rom.size > poor.size
    for theta in _random_thetas(cfg, 4, seed=21):
        f_full, _, kc, mc = _full(model, cfg, theta, 6)
        f_rom, _ = rom.solve(kc, mc)
        assert np.max(frequency_error(f_rom, f_full)) <= TOL


def test_residual_indicator_vanishes_at_a_training_point(coarse):
    """At a training point the ROM contains the exact modes: residual at round-off level there,
    clearly larger in the interior."""
    cfg, model, rom = coarse
    kc, mc = rom.coefficients(rom.report["training"][1]["theta"])  # a corner
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
