"""Harmonic stage (jointid.response.drive_point): modal superposition + residual against a direct solve on a small rig
model, the singular-K fallback, damping choices, and K_min = 2 zeta sqrt(1 - zeta^2) k for one mode."""

import json
from pathlib import Path

import numpy as np

from jointid.config.typed import Damping
import pandas as pd
import pytest

from jointid.response import damping as dm
from jointid.response import drive_point as frf
from jointid.response import harmonic as hm
from jointid.config import load_config
from jointid.errors import ConfigError, DataError, NumericalWarning
from jointid.fe.modal import Modes
from jointid.fe.model import base_coefficients, build_model, save_model
from jointid.stages import harmonic as harmonic_stage
from jointid.config.options import HarmonicOptions
from jointid.config.typed import ModelSpec

CONFIG = Path(__file__).resolve().parents[1] / "config.yaml"
BAND = (300.0, 3500.0)
THETA = {"k_normal_N_per_m3": 8e11, "k_lateral_N_per_m3": 8e11, "k_feed_N_per_m3": 1.5e10}


def small_cfg(support="clamped"):
    """The default rig on a very coarse linear (hex1) mesh: ~2.6e3 DOFs, built in well under a second."""
    return load_config(CONFIG, {"mesh.element": "hex1", "mesh.max_cell_size_m": 0.3,
                                "rig.support.kind": support})


@pytest.fixture(scope="module")
def rig():
    cfg = small_cfg()
    model = build_model(ModelSpec.from_config(cfg))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, THETA)
    K, M = model.K(kc), model.M(mc)
    modes = frf.solve_band_modes(K, M, BAND[1], fixed=model.fixed, n_start=12)
    p = frf.drive_vector(model, "T05", "y")
    return cfg, model, K, M, modes, p


def rayleigh_for(f_a, f_b, zeta):
    wa, wb = 2 * np.pi * f_a, 2 * np.pi * f_b
    return 2 * zeta * wa * wb / (wa + wb), 2 * zeta / (wa + wb)


def test_enough_modes_are_solved(rig):
    *_, modes, _ = rig
    assert modes.freqs_Hz[-1] >= frf.MODE_FACTOR * BAND[1]
    assert np.all(np.diff(modes.freqs_Hz) >= 0)


def test_one_factorisation_serves_the_modes_and_the_static_solve(rig):
    """solve_band_modes(keep_factor=True) gives the same modes, and the static residual refined on
    its K - sigma M factorisation equals the one from a factorisation of K itself."""
    cfg, model, K, M, modes, p = rig
    m2, shifted = frf.solve_band_modes(K, M, BAND[1], fixed=model.fixed, n_start=12, keep_factor=True)
    try:
        np.testing.assert_allclose(m2.freqs_Hz, modes.freqs_Hz, rtol=1e-9)
        assert shifted.sigma < 0 and len(shifted.free) == model.n_dofs - len(model.fixed)
        R, H0, note = hm.static_residual(K, p, m2.phi, m2.freqs_Hz, fixed=model.fixed, shifted=shifted)
    finally:
        shifted.free_memory()
    R0, H00, _ = hm.static_residual(K, p, modes.phi, modes.freqs_Hz, fixed=model.fixed)
    assert H0 == pytest.approx(H00, rel=1e-9)
    assert R == pytest.approx(R0, rel=1e-6, abs=1e-9 * H00)
    assert "residual" in note


def test_drive_vector_is_an_interpolation_row(rig):
    cfg, model, *_ , p = rig
    assert p.shape == (model.n_dofs,)
    nz = np.flatnonzero(p)
    assert np.all(nz % 3 == 1)  # only y components
    assert p.sum() == pytest.approx(1.0, abs=1e-9)  # partition of unity at the point
    with pytest.raises(ConfigError, match="T99:y"):
        frf.drive_vector(model, "T99", "y")


def test_modal_superposition_with_residual_matches_direct_solve(rig):
    """The issue's validation: within 1 % of (K - w^2 M + i w C) x = F away from resonances."""
    cfg, model, K, M, modes, p = rig
    fr = modes.freqs_Hz
    in_band = fr[(fr > BAND[0]) & (fr < BAND[1])]
    assert in_band.size >= 3  # a real multi-mode test
    alpha, beta = rayleigh_for(in_band[0], in_band[-1], 0.03)
    zeta, source = frf.modal_damping_ratios(Damping(model="rayleigh", alpha_per_s=alpha, beta_s=beta), fr)
    assert set(source) == {"rayleigh"}
    R, H0, note = hm.static_residual(K, p, modes.phi, fr, fixed=model.fixed)
    assert R is not None and R > 0 and "residual" in note
    res = frf.harmonic_response(modes, p, zeta, BAND, n_freq=120, residual=R, static_receptance=H0)
    # 16 frequencies away from every resonance (outside 2 half-power half-widths) and one near each peak
    grid = np.linspace(*BAND, 80) + 1.0
    zr = np.interp(grid, fr, zeta)
    away_grid = grid[np.min(np.abs(grid[:, None] - fr[None, :]) / fr[None, :], axis=1) > 2 * zr]
    assert away_grid.size >= 16
    f_away = away_grid[np.linspace(0, away_grid.size - 1, 16).round().astype(int)]
    f_peak = in_band * (1 + 0.1 * zeta[np.searchsorted(fr, in_band)])
    f = np.concatenate([f_away, f_peak])
    away = np.arange(f.size) < f_away.size
    C = dm.damping_matrix("rayleigh", K, M, alpha_per_s=alpha, beta_s=beta)
    h_direct = hm.direct_frf(K, M, C, p, f, fixed=model.fixed)
    pphi = p @ modes.phi
    h_modal = hm.frf_modal(f, fr, zeta, pphi, pphi, residual_flexibility=R)
    err = np.abs(h_modal - h_direct) / np.abs(h_direct)
    assert err[~away].max() < 0.05  # at the peaks too (the issue asks for 1 % away from them)
    assert err[away].max() < 0.01
    # without the residual the same comparison is clearly worse: the correction is doing work
    h0 = hm.frf_modal(f, fr, zeta, pphi, pphi)
    err0 = np.abs(h0 - h_direct) / np.abs(h_direct)
    assert err0[away].max() > 2 * err[away].max()
    # the band minimum agrees with the direct solve at the same frequency
    fmin = res.dynamic["f_at_min_Hz"]
    kd_direct = 1 / abs(hm.direct_frf(K, M, C, p, [fmin], fixed=model.fixed)[0])
    assert res.dynamic["k_dyn_min_N_per_m"] == pytest.approx(kd_direct, rel=0.01)


def test_static_stiffness_is_exact(rig):
    cfg, model, K, M, modes, p = rig
    R, H0, _ = hm.static_residual(K, p, modes.phi, modes.freqs_Hz, fixed=model.fixed)
    h_direct0 = hm.direct_frf(K, M, None, p, [0.0], fixed=model.fixed)[0]
    assert H0 == pytest.approx(h_direct0.real, rel=1e-9)
    res = frf.harmonic_response(modes, p, 0.02, BAND, n_freq=50, residual=R, static_receptance=H0)
    assert res.dynamic["k_static_N_per_m"] == pytest.approx(1 / h_direct0.real, rel=1e-9)
    # modal sum + residual reproduces H(0)
    pphi = p @ modes.phi
    assert np.sum(pphi**2 / (2 * np.pi * modes.freqs_Hz) ** 2) + R == pytest.approx(H0, rel=1e-12)


def test_free_model_falls_back_to_no_residual():
    cfg = small_cfg("free")
    model = build_model(ModelSpec.from_config(cfg))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, THETA)
    K, M = model.K(kc), model.M(mc)
    modes = frf.solve_band_modes(K, M, 1000.0, fixed=model.fixed, n_start=14, factor=2.0)
    assert np.sum(modes.freqs_Hz < frf.RIGID_HZ) == 6
    p = frf.drive_vector(model, "T05", "y")
    R, H0, note = hm.static_residual(K, p, modes.phi, modes.freqs_Hz, fixed=model.fixed)
    assert R is None and H0 is None and "rigid-body" in note
    zeta, source = frf.modal_damping_ratios(Damping(model="modal", damping_ratio=0.03), modes.freqs_Hz)
    assert source.count("rigid") == 6 and np.all(zeta[:6] == 0) and np.all(zeta[6:] == 0.03)
    res = frf.harmonic_response(modes, p, zeta, (300.0, 1000.0), n_freq=50, residual=R, static_receptance=H0)
    assert res.dynamic["k_static_N_per_m"] is None
    assert np.all(np.isfinite(res.H))


def test_single_mode_minimum_is_two_zeta_k():
    """One mode, unit participation: K_min = 2 zeta sqrt(1 - zeta^2) k at f_r sqrt(1 - 2 zeta^2)."""
    f0, zeta = 1500.0, 0.03
    k = (2 * np.pi * f0) ** 2  # unit modal mass
    modes = Modes(freqs_Hz=np.array([f0]), phi=np.array([[1.0]]))
    res = frf.harmonic_response(modes, np.array([1.0]), [zeta], BAND, n_freq=200)
    assert res.dynamic["k_dyn_min_N_per_m"] == pytest.approx(2 * zeta * np.sqrt(1 - zeta**2) * k, rel=1e-3)
    assert res.dynamic["f_at_min_Hz"] == pytest.approx(f0 * np.sqrt(1 - 2 * zeta**2), rel=2e-3)
    assert res.governing == 0


def test_damping_choices():
    f = np.array([0.0, 500.0, 1500.0, 2500.0])
    z, src = frf.modal_damping_ratios(Damping(model="modal", damping_ratio=0.02), f, measured={2: 0.05})
    np.testing.assert_allclose(z, [0, 0.02, 0.05, 0.02])
    assert src == ["rigid", "modal", "measured", "modal"]
    z, src = frf.modal_damping_ratios(Damping(model="measured"), f, measured={1: 0.01, 2: 0.03})
    np.testing.assert_allclose(z, [0, 0.01, 0.03, 0.02])
    assert src[3] == "mean measured"
    with pytest.raises(DataError, match="damping_ratio column"):
        frf.modal_damping_ratios(Damping(model="measured"), f)
    with pytest.warns(NumericalWarning, match="zero damping"):
        z, _ = frf.modal_damping_ratios(Damping(model="joint", joint_loss_factor_s=1e-5), f,
                                        joint_share=[0, 0.5, 0.5, 0.0])
    np.testing.assert_allclose(z, [0, 1e-5 * 2 * np.pi * 500 * 0.5 / 2, 1e-5 * 2 * np.pi * 1500 * 0.5 / 2, 0])


def test_run_harmonic_stage(tmp_path, rig):
    cfg, model, *_ = rig
    cfg = dict(cfg, measurements={"dataset": str(CONFIG.parent / "data" / "paper")})  # independent of the cwd
    save_model(model, tmp_path / "matrices.npz")
    params = {"parameters": {n: {"value": v, "ci95_low": v, "ci95_high": v} for n, v in THETA.items()}}
    (tmp_path / "params.json").write_text(json.dumps(params))
    pd.DataFrame({"order": [1, 2], "fe_mode": [1, 0]}).to_csv(tmp_path / "verify.csv", index=False)
    out = harmonic_stage.run_harmonic(
        HarmonicOptions.from_config(cfg, "power_off"), "power_off", str(tmp_path / "params.json"), str(tmp_path / "matrices.npz"),
        str(tmp_path / "frf.csv"), str(tmp_path / "ds.json"), out_modes=str(tmp_path / "m.npz"),
        verify_csv=str(tmp_path / "verify.csv"), out_points=str(tmp_path / "pts.npz"), progress=lambda m: None)
    tab = pd.read_csv(tmp_path / "frf.csv")
    assert list(tab.columns) == ["freq_Hz", "H_real_m_per_N", "H_imag_m_per_N", "H_abs_m_per_N", "phase_deg",
                                 "dynamic_stiffness_N_per_m"]
    assert tab.freq_Hz.min() == BAND[0] and tab.freq_Hz.max() == BAND[1]
    assert tab.dynamic_stiffness_N_per_m.min() == pytest.approx(out["dynamic_stiffness_N_per_m"], rel=1e-9)
    doc = json.loads((tmp_path / "ds.json").read_text())
    assert doc["damping"]["config"] == {"model": "modal", "damping_ratio": 0.03}
    assert "no damping ratios" in doc["damping"]["measured"]  # data/paper has none
    assert doc["residual"]["used"] is True
    assert doc["static_stiffness_N_per_m"] > doc["dynamic_stiffness_N_per_m"]
    g = doc["governing_mode"]
    assert BAND[0] < g["freq_Hz"] < BAND[1]
    z = np.load(tmp_path / "m.npz")
    assert z["shapes"].shape == (108, z["freqs_Hz"].size)
    # Table 1's status: identified only if the governing mode is paired (here only FE mode 1 is)
    assert doc["patch_diameter_m"] == 0.010
    assert (doc["status"] == "identified") == (g["fe_mode"] == 1)
    if g["fe_mode"] != 1:
        assert doc["status"].startswith(f"not identified: the governing mode (FE mode {g['fe_mode']}, ")
    pm = doc["paired_minimum"]
    assert pm is None or (pm["fe_mode"] == 1 and pm["dynamic_stiffness_N_per_m"] >= doc["dynamic_stiffness_N_per_m"])
    pts = np.load(tmp_path / "pts.npz")
    assert list(pts["points"]) == [f"T{i:02d}" for i in range(1, 19)]
    assert pts["pphi"].shape == (18, z["freqs_Hz"].size) and pts["measured_order"].tolist()[:2] == [1, 0]
    k5 = 4  # T05: its patch participation is the drive point's
    np.testing.assert_allclose(pts["pphi"][k5], z["participation"], rtol=1e-10, atol=1e-12 * np.abs(z["participation"]).max())
