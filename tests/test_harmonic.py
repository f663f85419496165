"""FRFs, residual flexibility, dynamic stiffness and damping models against analytic references."""

import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from jointid.response import damping as dm
from jointid.response import harmonic as hm
from jointid.errors import ConfigError, DataError, ModelError, NumericalWarning


def chain(masses, springs, grounded=True):
    """Spring-mass chain; spring i joins mass i-1 and mass i, spring 0 joins mass 0 to ground."""
    m = np.asarray(masses, float)
    k = np.asarray(springs, float)
    n = m.size
    main = k.copy()
    main[:-1] += k[1:]
    if not grounded:
        main[0] -= k[0]
    K = sp.diags([main, -k[1:], -k[1:]], [0, -1, 1], format="csr")
    return K, sp.diags(m, format="csr")


def modes(K, M):
    w2, phi = sla.eigh(K.toarray(), M.toarray())
    return np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi), phi


def rayleigh_for(f_a, f_b, zeta):
    """alpha, beta giving `zeta` at f_a and f_b."""
    wa, wb = 2 * np.pi * f_a, 2 * np.pi * f_b
    return 2 * zeta * wa * wb / (wa + wb), 2 * zeta / (wa + wb)


# ---------------------------------------------------------------- (1) 3-DOF: modal == direct
def test_three_dof_modal_superposition_equals_direct_solve():
    K, M = chain([2.0, 1.0, 1.5], [3e5, 2e5, 1e5])
    f, phi = modes(K, M)
    alpha, beta = rayleigh_for(f[0], f[2], 0.03)
    zeta = dm.modal_damping(f, "rayleigh", alpha_per_s=alpha, beta_s=beta)
    C = dm.damping_matrix("rayleigh", K, M, alpha_per_s=alpha, beta_s=beta)
    grid = np.unique(np.concatenate([np.linspace(0.0, 2 * f[-1], 400), f, f * 1.001]))
    resp = np.array([0, 1, 2])
    h_modal = hm.frf_modal(grid, f, zeta, phi[2], phi[resp])
    h_direct = hm.direct_frf(K, M, C, np.eye(3)[2], grid, response=np.eye(3)[resp])
    assert h_modal.shape == h_direct.shape == (grid.size, 3)
    err = np.abs(h_modal - h_direct) / np.abs(h_direct)
    assert err.max() < 1e-8
    # reciprocity of the direct solve: H_02 == H_20
    np.testing.assert_allclose(hm.direct_frf(K, M, C, np.eye(3)[0], grid, response=np.eye(3)[2]), h_direct[:, 0],
                               rtol=1e-10)


# ---------------------------------------------------------------- (2) truncation + residual
@pytest.fixture(scope="module")
def chain40():
    rng = np.random.default_rng(0)
    K, M = chain(rng.uniform(0.8, 1.2, 40), rng.uniform(0.8, 1.2, 40) * 1e6)
    f, phi = modes(K, M)
    alpha, beta = rayleigh_for(f[0], f[5], 0.02)
    zeta = dm.modal_damping(f, "rayleigh", alpha_per_s=alpha, beta_s=beta)
    C = dm.damping_matrix("rayleigh", K, M, alpha_per_s=alpha, beta_s=beta)
    return K, M, C, f, phi, zeta


def truncated_errors(chain40, drive, resp, grid, n_keep=6):
    K, M, C, f, phi, zeta = chain40
    load = np.zeros(K.shape[0])
    load[drive] = 1.0
    r = hm.static_residual(K, load, phi[:, :n_keep], f[:n_keep], response=np.eye(K.shape[0])[resp])[0]
    h_d = hm.direct_frf(K, M, C, load, grid, response=np.eye(K.shape[0])[resp])
    args = (grid, f[:n_keep], zeta[:n_keep], phi[drive, :n_keep], phi[resp, :n_keep])
    e_res = np.abs(hm.frf_modal(*args, residual_flexibility=r) - h_d) / np.abs(h_d)
    e_nores = np.abs(hm.frf_modal(*args) - h_d) / np.abs(h_d)
    return e_res, e_nores


def away_from_resonances(f, f_top, n=3000):
    grid = np.linspace(0.0, f_top, n)
    keep = np.ones(grid.size, bool)
    for fr in f:
        keep &= np.abs(grid / fr - 1) > 0.03
    return grid[keep]


def test_residual_flexibility_restores_truncated_modes(chain40):
    f = chain40[3]
    # band 0 .. 0.4 f7 (3 resonances), end-to-end transfer FRF (no antiresonances), 6 of 40 modes kept
    grid = away_from_resonances(f[:7], 0.4 * f[6])
    e_res, e_nores = truncated_errors(chain40, 39, 0, grid)
    assert e_res.max() < 0.01
    assert e_nores.max() > 0.02 and e_nores.max() > 3 * e_res.max()


def test_residual_is_static_only_and_degrades_towards_next_mode(chain40):
    f = chain40[3]
    grid = away_from_resonances(f[:7], 0.97 * f[6])
    e_res, _ = truncated_errors(chain40, 39, 0, grid)
    assert e_res[grid < 0.4 * f[6]].max() < 0.01
    assert e_res[grid > 0.6 * f[6]].max() > 0.02     # the documented limit: not a dynamic correction


def test_residual_gives_exact_static_point_receptance(chain40):
    K, M, C, f, phi, zeta = chain40
    load = np.zeros(40)
    load[39] = 1.0
    r = hm.static_residual(K, load, phi[:, :6], f[:6])[0]
    h0 = hm.frf_modal([0.0], f[:6], zeta[:6], phi[39, :6], phi[39, :6], residual_flexibility=r)[0]
    x_static = sp.linalg.spsolve(K.tocsc(), load)[39]
    assert abs(h0 - x_static) / x_static < 1e-10


def test_truncated_point_frf_gives_kmin_of_full_model(chain40):
    K, M, C, f, phi, zeta = chain40
    load = np.zeros(40)
    load[39] = 1.0
    r = hm.static_residual(K, load, phi[:, :6], f[:6])[0]
    grid = hm.resonance_grid(0.5 * f[0], 0.4 * f[6], f[:6], zeta[:6])
    h_t = hm.frf_modal(grid, f[:6], zeta[:6], phi[39, :6], phi[39, :6], residual_flexibility=r)
    k_t = hm.dynamic_stiffness(grid, h_t)
    k_d = hm.dynamic_stiffness(grid, hm.direct_frf(K, M, C, load, grid))
    assert abs(k_t["k_dyn_min_N_per_m"] / k_d["k_dyn_min_N_per_m"] - 1) < 0.01
    assert k_t["f_at_min_Hz"] == k_d["f_at_min_Hz"]


def test_singular_stiffness_raises_model_error():
    K, M = chain([1.0, 1.0, 1.0], [1e5, 1e5, 1e5], grounded=False)   # free-free: rigid-body mode
    with pytest.raises(ModelError, match="constrain the model"):
        hm.static_solver(K)
    f, phi = modes(K, M)
    R, H0, note = hm.static_residual(K, np.eye(3)[0], phi, f)  # no residual, and why
    assert R is None and H0 is None and "rigid-body" in note


# ---------------------------------------------------------------- (3) SDOF dynamic stiffness
@pytest.mark.parametrize("zeta", [0.02, 0.1, 0.3])
def test_sdof_minimum_dynamic_stiffness(zeta):
    m, k = 2.0, 3.0e7
    fn = np.sqrt(k / m) / (2 * np.pi)
    grid = hm.resonance_grid(0.3 * fn, 3 * fn, [fn], [zeta])
    phi = np.array([1 / np.sqrt(m)])
    h = hm.frf_modal(grid, [fn], zeta, phi, phi)
    h0 = hm.frf_modal([0.0], [fn], zeta, phi, phi)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        out = hm.dynamic_stiffness(grid, h, H0=h0)
    expected = 2 * zeta * k * np.sqrt(1 - zeta**2)
    assert abs(out["k_dyn_min_N_per_m"] / expected - 1) < 0.005
    assert abs(out["f_at_min_Hz"] / (fn * np.sqrt(1 - 2 * zeta**2)) - 1) < 0.01
    assert out["k_static_N_per_m"] == pytest.approx(k, rel=1e-12)
    assert hm.governing_mode(out["f_at_min_Hz"], [0.3 * fn, fn, 2.5 * fn]) == 1


def test_coarse_grid_and_band_edge_warn():
    m, k, zeta = 1.0, 1e6, 0.01
    fn = np.sqrt(k / m) / (2 * np.pi)
    phi = np.array([1.0])
    coarse = np.linspace(0.5 * fn, 1.5 * fn, 21)        # step 5 % >> half-power bandwidth 2 %
    coarse = coarse + 0.02 * fn                           # miss the peak
    with pytest.warns(NumericalWarning, match="under-resolved"):
        hm.dynamic_stiffness(coarse, hm.frf_modal(coarse, [fn], zeta, phi, phi))
    below = np.linspace(0.1 * fn, 0.5 * fn, 50)
    with pytest.warns(NumericalWarning, match="band edge"):
        hm.dynamic_stiffness(below, hm.frf_modal(below, [fn], zeta, phi, phi))


def test_dynamic_stiffness_rejects_bad_grid():
    with pytest.raises(DataError, match="increasing"):
        hm.dynamic_stiffness([1.0, 3.0, 2.0], [1, 1, 1])


# ---------------------------------------------------------------- damping models
def test_rayleigh_and_joint_ratios_match_modal_projection_of_C():
    K, M = chain([2.0, 1.0, 1.5, 0.7], [3e5, 2e5, 1e5, 4e5])
    f, phi = modes(K, M)
    w = 2 * np.pi * f
    alpha, beta = 12.0, 2e-5
    C = dm.damping_matrix("rayleigh", K, M, alpha_per_s=alpha, beta_s=beta)
    np.testing.assert_allclose(dm.modal_damping(f, "rayleigh", alpha_per_s=alpha, beta_s=beta),
                               np.diag(phi.T @ C @ phi) / (2 * w), rtol=1e-12)
    np.testing.assert_allclose(dm.modal_damping(f, "rayleigh", alpha_per_s=alpha, beta_s=beta),
                               alpha / (2 * w) + beta * w / 2, rtol=1e-12)
    # joints = springs 0 and 2 of the chain
    K_joint, _ = chain([1, 1, 1, 1], [3e5, 0.0, 1e5, 0.0])
    share = dm.joint_energy_share(phi, f, K_joint)
    assert np.all((share > 0) & (share < 1))
    eta = 3e-5
    zeta = dm.modal_damping(f, "joint", joint_loss_factor_s=eta, joint_energy_share=share)
    C_j = dm.damping_matrix("joint", K, M, K_joint=K_joint, joint_loss_factor_s=eta)
    np.testing.assert_allclose(zeta, np.diag(phi.T @ C_j @ phi) / (2 * w), rtol=1e-12)
    np.testing.assert_allclose(dm.joint_energy_share(phi, f, K), 1.0, rtol=1e-12)


def test_modal_damping_matrix_reproduces_ratios():
    K, M = chain([2.0, 1.0, 1.5], [3e5, 2e5, 1e5])
    f, phi = modes(K, M)
    zeta = dm.modal_damping(f, "measured", measured=[0.01, 0.02, 0.05])
    C = dm.damping_matrix("modal", K, M, phi=phi, freqs_Hz=f, zeta=zeta)
    np.testing.assert_allclose(phi.T @ C @ phi, np.diag(2 * zeta * 2 * np.pi * f), atol=1e-9)
    np.testing.assert_array_equal(dm.modal_damping(f, "modal", damping_ratio=0.02), [0.02] * 3)


def test_damping_model_errors():
    f = [100.0, 200.0]
    with pytest.raises(ConfigError, match="unknown"):
        dm.modal_damping(f, "hysteretic")
    with pytest.raises(ConfigError, match="beta_s: missing"):
        dm.modal_damping(f, "rayleigh", alpha_per_s=1.0)
    with pytest.raises(ConfigError, match="damping_ratio is set but damping.model is 'rayleigh'"):
        dm.modal_damping(f, "rayleigh", alpha_per_s=1.0, beta_s=0.0, damping_ratio=0.02)
    with pytest.raises(DataError, match="3 values for 2 modes"):
        dm.modal_damping(f, "measured", measured=[0.01, 0.02, 0.03])
    with pytest.raises(ModelError, match="> 0 Hz"):
        dm.modal_damping([0.0, 10.0], "modal", damping_ratio=0.02)
    with pytest.warns(NumericalWarning, match="overdamped"):
        dm.modal_damping(f, "modal", damping_ratio=1.5)
