"""Numerical guards: rigid-body modes, a shift on an eigenvalue, an optimum on a DOE bound, an
ill-conditioned identification, and a config that fails validation before any job runs."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import REPO, copy_workflow, run_snakemake, write_config
from jointid.identification import doe
from jointid.config import load_config
from jointid.errors import ModelError, NumericalWarning
from jointid.identification.identify import identify
from jointid.fe.modal import solve_modes
from jointid.fe.model import base_coefficients, build_model
from jointid.geometry.points import dof_labels
from jointid.identification.surface import fit_surface
from jointid.identification.updating import identify_state
from jointid.config.typed import ModelSpec

BACKENDS = ["pardiso", "scipy"]
N_MODES = 8


@pytest.fixture(scope="module")
def cfg():
    overrides = yaml.safe_load((REPO / "tests" / "coarse_config.yaml").read_text())
    return load_config(REPO / "config.yaml", overrides=overrides)


@pytest.fixture(scope="module")
def model(cfg):
    return build_model(ModelSpec.from_config(cfg))


def _solve(model, cfg, theta, shift_Hz, backend):
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, theta)
    return solve_modes(model.K(kc), model.M(mc), N_MODES, shift_Hz=shift_Hz, fixed=model.fixed,
                       backend=backend)


def _zero_joints(cfg, scale=0.0):
    return {n: scale * p["lower"] for n, p in cfg["joints"]["parameters"].items()}


# ------------------------------------------------------------------ rigid-body modes
@pytest.fixture(scope="module")
def solved(model, cfg):
    """Cached solves: ``solved(joints, shift_Hz, backend)`` with joints "zero" or "default"."""
    cache = {}

    def get(joints, shift_Hz, backend):
        key = (joints, shift_Hz, backend)
        if key not in cache:
            theta = _zero_joints(cfg) if joints == "zero" else None
            cache[key] = _solve(model, cfg, theta, shift_Hz, backend)
        return cache[key]

    return get


@pytest.mark.parametrize("backend, scale", [("pardiso", 0.0), ("scipy", 0.0), ("pardiso", 1e-9)],
                         ids=["zero-pardiso", "zero-scipy", "near_zero-pardiso"])
def test_free_carriage_assembly_gives_six_rigid_body_modes(model, cfg, solved, backend, scale):
    """Joint stiffness -> 0: table, carriages and motors float; 6 modes at ~0 Hz, the rest elastic."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        if scale == 0.0:
            modes = solved("zero", -10.0, backend)
        else:
            modes = _solve(model, cfg, _zero_joints(cfg, scale), -10.0, backend)
    f = modes.freqs_Hz
    assert np.all(np.isfinite(f)) and np.all(np.diff(f) >= 0)
    assert np.all(f[:6] < 0.5), f"rigid-body modes at {f[:6]} Hz"
    assert f[6] > 100.0, f"first elastic mode at {f[6]} Hz"
    # the base (B points, clamped below) stays still while the floating assembly (T points) moves
    labels = np.array(dof_labels(pd.DataFrame(model.meta["points"])))
    shapes = model.probe @ modes.phi[:, :6]
    top = np.char.startswith(labels, "T")
    base = np.char.startswith(labels, "B")
    assert np.abs(shapes[base]).max() < 1e-6 * np.abs(shapes[top]).max()


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_stiffness_at_shift_zero_gives_right_modes_or_a_clear_error(model, cfg, solved, backend):
    """K - 0*M is singular with free joints. A backend may refuse it (then: one line naming the cause and
    the fix) or factorise it with pivot perturbation (then the modes must still be right); it must never
    return wrong modes silently."""
    ref = solved("zero", -10.0, backend).freqs_Hz
    try:
        got = _solve(model, cfg, _zero_joints(cfg), 0.0, backend).freqs_Hz
    except ModelError as exc:
        msg = str(exc)
        assert len(exc.problems) == 1 and "\n" not in msg
        assert "singular" in msg and "joint stiffness" in msg and "negative solver.shift_Hz" in msg
        return
    assert np.all(got[:6] < 0.5)
    np.testing.assert_allclose(got[6:], ref[6:], rtol=1e-8)


def test_block_lanczos_on_a_singular_shifted_matrix_falls_back_to_the_right_modes(model, cfg, solved, monkeypatch):
    """At shift 0 with free joints SuperLU factorises the singular K - 0*M; block Lanczos then
    converges to wrong elastic pairs (13 and 43 Hz for 990 and 1389 Hz), which only their true
    residual shows.  The check rejects them and single-vector Lanczos gives the right modes."""
    import jointid.fe.blocklanczos as bl
    import jointid.fe.modal as fm

    ref = solved("zero", -10.0, "scipy").freqs_Hz
    monkeypatch.setattr(fm, "MIN_DOFS", 5000)  # the block method on the coarse model
    residuals = []

    def spy(Kf, Mf, lam, X):
        residuals.append(bl.true_residual(Kf, Mf, lam, X))
        return residuals[-1]

    monkeypatch.setattr(fm, "true_residual", spy)
    got = _solve(model, cfg, _zero_joints(cfg), 0.0, "scipy").freqs_Hz
    assert len(residuals) == 1 and residuals[0] > bl.RESIDUAL_TOL  # tried, and rejected
    assert np.all(got[:6] < 0.5)
    np.testing.assert_allclose(got[6:], ref[6:], rtol=1e-8)
    # and at a regular shift the block answer passes the same check
    residuals.clear()
    _solve(model, cfg, None, -10.0, "scipy")
    assert len(residuals) == 1 and residuals[0] <= bl.RESIDUAL_TOL


# ------------------------------------------------------------------ shift on an eigenvalue
@pytest.mark.parametrize("backend, which", [("pardiso", 0), ("pardiso", 2), ("scipy", 2)],
                         ids=["first-pardiso", "third-pardiso", "third-scipy"])
def test_shift_on_an_eigenvalue_gives_right_modes_or_a_clear_error(model, cfg, solved, backend, which):
    ref = solved("default", -10.0, backend).freqs_Hz
    shift = float(ref[which])  # exactly on a natural frequency: K - sigma M is singular
    try:
        got = _solve(model, cfg, None, shift, backend).freqs_Hz
    except ModelError as exc:
        msg = str(exc)
        assert "\n" not in msg and "solver.shift_Hz" in msg and "negative" in msg
        return
    np.testing.assert_allclose(got, ref, rtol=1e-8)


def test_too_many_modes_for_the_model_is_a_model_error():
    import scipy.sparse as sp

    K = sp.diags([1.0, 2.0, 3.0, 4.0]).tocsr()
    with pytest.raises(ModelError, match=r"solver\.n_modes: 3 modes requested but the model has only 4 "
                                         r"free DOFs — lower solver\.n_modes"):
        solve_modes(K, sp.identity(4, format="csr"), 3)


# ------------------------------------------------------------------ identification guards
NAMES = ["k_normal_N_per_m3", "k_feed_N_per_m3"]
LOWER = np.array([2.0e11, 3.0e9])
UPPER = np.array([4.0e12, 6.0e10])


def freqs_separable(k):
    """Three modes: normal only, feed only, and both (Hz); k in N/m^3."""
    kn, kf = k
    return np.array([300.0 * np.sqrt(kn / 1e12), 900.0 * np.sqrt(kf / 1e10),
                     1500.0 * np.sqrt((kn / 1e12 + kf / 1e10) / 2)])


def freqs_product_only(k):
    """Every mode depends on kn * kf only: the ratio kn / kf cannot be identified."""
    kn, kf = k
    g = (kn / 1e12 * kf / 1e10) ** 0.25
    return np.array([400.0, 1300.0, 2100.0]) * g


def _coded(fun):
    return lambda x: fun(doe.to_physical(np.asarray(x, float), LOWER, UPPER))


def _surface_doc(fun):
    """A quadratic surface of ln f over a CCF, in the layout of results/surface/model.json."""
    X = doe.design("ccf", 2, n_center=1)
    Y = np.log(np.array([_coded(fun)(x) for x in X]))
    return {"names": NAMES, "surface": fit_surface(X, Y).to_dict(), "tracked_modes": [1, 2, 3],
            "lower": LOWER.tolist(), "upper": UPPER.tolist()}


BOUND_MSG = re.compile(r"k_normal_N_per_m3 sits on its upper bound 4e12: the surface is extrapolating "
                       r".*widen joints\.parameters\.k_normal_N_per_m3 bounds")


def test_optimum_on_a_doe_bound_warns_to_widen_the_bounds():
    f_meas = freqs_separable([9.0e12, 1.0e10])  # k_normal beyond the upper bound 4e12
    with pytest.warns(NumericalWarning, match=BOUND_MSG):
        res = identify(_coded(freqs_separable), f_meas, names=NAMES, lower=LOWER, upper=UPPER, seed=3)
    assert res.on_bound == ["k_normal_N_per_m3"]
    assert res.theta[0] == pytest.approx(4.0e12, rel=1e-3)


def test_optimum_on_a_bound_reaches_the_stage_warnings():
    """identify_state returns the warning text that run_identify stores in params.json."""
    f_meas = freqs_separable([9.0e12, 1.0e10])
    res, pairing, msgs = identify_state(_surface_doc(freqs_separable), f_meas, LOWER, UPPER,
                                        n_starts=4, seed=0)
    assert list(pairing) == [0, 1, 2]
    assert any(BOUND_MSG.search(m) for m in msgs), msgs
    assert res.on_bound == ["k_normal_N_per_m3"]


def test_no_warning_for_an_optimum_inside_the_box():
    f_meas = freqs_separable([1.0e12, 1.0e10])
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        res = identify(_coded(freqs_separable), f_meas, names=NAMES, lower=LOWER, upper=UPPER, seed=3)
    np.testing.assert_allclose(res.theta, [1.0e12, 1.0e10], rtol=1e-6)
    assert res.identifiable and res.on_bound == []


ILL_MSG = re.compile(r"identify: (0\.71\*k_normal_N_per_m3 - 0\.71\*k_feed_N_per_m3|"
                     r"0\.71\*k_feed_N_per_m3 - 0\.71\*k_normal_N_per_m3) \(in log10\) is not "
                     r"identifiable from these data .*fix one of these parameters")


def test_ill_conditioned_identification_warns_and_names_the_combination():
    f_meas = freqs_product_only([1.0e12, 1.0e10])
    with pytest.warns(NumericalWarning, match=ILL_MSG):
        res = identify(_coded(freqs_product_only), f_meas, names=NAMES, lower=LOWER, upper=UPPER,
                       seed=3)
    assert not res.identifiable
    assert "k_normal_N_per_m3" in res.weak_combination and "k_feed_N_per_m3" in res.weak_combination
    # the product is still determined: log10(kn) + log10(kf) = 22
    assert np.log10(res.theta).sum() == pytest.approx(22.0, abs=1e-6)


def test_ill_conditioned_identification_reaches_the_stage_warnings():
    f_meas = freqs_product_only([1.0e12, 1.0e10])
    res, _, msgs = identify_state(_surface_doc(freqs_product_only), f_meas, LOWER, UPPER,
                                  n_starts=4, seed=0)
    assert any(ILL_MSG.search(m) for m in msgs), msgs
    assert res.weak_combination is not None


# ------------------------------------------------------------------ config that fails validation
@pytest.mark.slow
def test_invalid_config_stops_the_dry_run_with_one_line_per_problem(tmp_path):
    wd = copy_workflow(tmp_path / "wf")
    bad = write_config(wd / "bad.yaml", "joints:\n  parameters:\n"
                       "    k_normal_N_per_m3: {direction: y, lower: 4.0e+12, upper: 2.0e+11}\n"
                       "identify:\n  frequency_uncertainty_pct: -1.0\n")
    proc = run_snakemake(wd, "-n", "-j1", configs=[bad])
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Traceback" not in out and "Exception" not in out, out
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    bounds = [ln for ln in lines if "joints.parameters.k_normal_N_per_m3" in ln]
    sigma = [ln for ln in lines if "identify.frequency_uncertainty_pct" in ln]
    assert len(bounds) == 1 and "inverted" in bounds[0] and "swap" in bounds[0], proc.stderr
    assert len(sigma) == 1 and "-1" in sigma[0], proc.stderr
    for ln in bounds + sigma:  # where (the overlay that set the key): what — how to fix
        assert ln.startswith(f"{bad}: ") and " — " in ln, ln
    assert not (wd / "results").exists() and not (wd / "logs").exists()
