"""Measured shapes in the identification's polish (issue 50: shapes in every fit by default).

Analytic references: the modal-superposition shape sensitivity against finite differences on a small
eigenproblem whose modes are all kept (then the superposition is exact); the two-block covariance
against its closed form.  Known truth: a synthetic state with shapes, identified from a start far from
the truth by the API's polish: the shape block enters, and the intervals hold the truth."""

from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import eigh

from jointid.identification.polish_shapes import block_covariance, shape_sensitivity

ROOT = Path(__file__).resolve().parents[1]


def _modes(K0, K1, M, theta):
    lam, phi = eigh(K0 + theta * K1, M)
    return lam, phi


def test_shape_sensitivity_is_exact_with_all_modes_kept():
    rng = np.random.default_rng(4)
    n = 6
    A, B, C = (rng.standard_normal((n, n)) for _ in range(3))
    K0, K1 = A @ A.T + n * np.eye(n), B @ B.T
    M = C @ C.T + n * np.eye(n)
    probe = rng.standard_normal((3, n))
    theta, cols = 2.0, [1, 4]
    lam, phi = _modes(K0, K1, M, theta)
    got = shape_sensitivity({"k1": K1}, phi, lam, probe @ phi, [{"k1": 1.0}], np.array([theta]), cols)
    h = 1e-6  # central difference in log10 theta, signs aligned with the unperturbed modes
    fd = []
    for sgn in (1, -1):
        _, ph = _modes(K0, K1, M, theta * 10 ** (sgn * h))
        ph = ph * np.sign(np.sum(ph * (M @ phi), axis=0))
        fd.append(probe @ ph[:, cols])
    fd = (fd[0] - fd[1]) / (2 * h)
    np.testing.assert_allclose(got[:, :, 0], fd, rtol=1e-5, atol=1e-8)


def test_close_modes_leave_their_rotation_out_of_both_shape_derivatives():
    # diagonal K0, M = I: the modes are the unit vectors and the derivative of mode 0 along dK is
    # dK[k, 0] / (lam_0 - lam_k) on every other mode k (analytic); modes 0 and 1 are 0.05 % apart
    from types import SimpleNamespace

    from jointid.fe.reduced import Solution
    from jointid.fe.shape_derivative import CLOSE_MODE_GAP, close_modes, probe_shape_derivatives

    lam = np.array([1.0, 1.001, 2.0, 3.5, 5.0])
    n = len(lam)
    rng = np.random.default_rng(7)
    B = rng.standard_normal((n, n))
    dK = B + B.T
    probe = rng.standard_normal((3, n))
    want = np.array([dK[k, 0] / (lam[0] - lam[k]) if k > 1 else 0.0 for k in range(n)])  # mode 1 left out
    assert 1.001 - 1.0 < CLOSE_MODE_GAP and list(close_modes(lam, lam[0])) == [1]
    # the polish's modal superposition (theta 1: d/dlog10 theta carries ln 10)
    sup = shape_sensitivity({"d": dK}, np.eye(n), lam, probe, [{"d": 1.0}], np.array([1.0]), [0])
    np.testing.assert_allclose(sup[:, 0, 0], probe @ want * np.log(10), rtol=1e-12, atol=1e-12)
    # the diagnosis's bordered Nelson solve on the same pencil
    solver = SimpleNamespace(Kr={"K0": np.diag(lam), "d": dK}, Mr={"M0": np.eye(n)}, PV=probe)
    sol = Solution(np.sqrt(lam) / (2 * np.pi), lam, np.eye(n), lam, np.eye(n), {}, {}, probe)
    nel = probe_shape_derivatives(solver, sol, [0], [({"d": 1.0}, {})])
    np.testing.assert_allclose(nel[:, 0, 0], probe @ want, rtol=1e-9, atol=1e-12)
    # without the close mode the rotation term is 1000 times the others: what is left out
    assert abs(dK[1, 0] / (lam[0] - lam[1])) > 100 * np.abs(want).max()


def test_block_covariance_weights_each_block_by_its_own_lack_of_fit():
    # two frequency rows (noise right: chi2/dof <= 1) and shape rows at 3x their noise, one parameter
    J = np.array([[1.0], [2.0], [1.0], [1.0], [1.0], [1.0]])
    r = np.array([0.5, -0.5, 3.0, -3.0, 3.0, -3.0])
    modes = np.array([0, 0, 1, 1])  # two shape rows for each of two measured modes
    out = block_covariance(J, r, 2, 1, modes)
    assert out["shape_dof"] == 2 and out["shape_chi2"] == pytest.approx(36.0)
    c_s = 36.0 / 2
    info = (1 + 4) / 1.0 + 4 * 1.0 / c_s  # the frequency block at c = 1, the shape block at its own c
    assert out["cov"][0, 0] >= 1 / info * (1 - 1e-12)  # the cluster-robust check can only widen
    assert out["cov"][0, 0] == pytest.approx(out["cluster_factor"] / info, rel=1e-12)


@pytest.fixture(scope="module")
def study():
    from jointid import Study

    return Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])


def test_a_state_with_shapes_is_identified_with_its_shape_block(study, tmp_path):
    truth_k = {"k_normal_N_per_m3": 9.0e11, "k_lateral_N_per_m3": 5.0e11}
    feed = study.config["joints"]["parameters"]["k_feed_N_per_m3"]
    truth_k["k_feed_N_per_m3"] = float(np.sqrt(feed["lower"] * feed["upper"]))
    truth = {"joints": truth_k, "states": {"power_off": {"em_force_N": 0.0}},
             "measurement": {"band_Hz": [100.0, 3500.0], "max_modes": 8, "shapes": True},
             "noise": {"seed": 21, "frequency_pct": 0.2, "shape_pct": 2.0}}
    ds = study.synthetic_dataset(truth, tmp_path / "ds")
    start = {k: 1.6 * v for k, v in truth_k.items()}
    ident = study.identify(ds, "power_off", theta0=start, log=lambda m: None)
    assert ident.paired_by == "mac"
    assert ident.shape_dof > 50, ident.shape_dof
    # the truth's own shapes at their stated 2 % (on the analysis's own mesh): chi2/dof near 1
    assert 0.6 < ident.shape_chi2 / ident.shape_dof < 1.6, (ident.shape_chi2, ident.shape_dof)
    for k, v in truth_k.items():
        assert ident.ci95_low[k] <= v <= ident.ci95_high[k], (k, v, ident.ci95_low[k], ident.ci95_high[k])
