"""Mesh extrapolation over edge-refinement levels: Aitken's limit, following modes, the corrected solve."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointid.fe.extrapolate import FrequencyCorrection, aitken, aitken_weights, edge_limit, geometric_limit
from jointid.identification.polish import corrected as _corrected
from jointid.identification.polish import log_jacobian
from test_localrefine import _cantilever_freqs


@settings(max_examples=200, deadline=None)
@given(limit=st.floats(50.0, 5000.0), drop=st.floats(1e-4, 0.05), r=st.floats(0.05, 0.79))
def test_aitken_recovers_the_limit_of_a_geometric_sequence(limit, drop, r):
    f = [limit * (1 + drop * r**k) for k in range(3)]
    lim, ratio, status = aitken(*f)
    assert status == "extrapolated"
    assert ratio == pytest.approx(r, rel=1e-6)
    assert lim == pytest.approx(limit, rel=1e-9)


def test_aitken_refuses_sequences_outside_the_asymptotic_range():
    f0 = np.array([100.0, 100.0, 100.0, 100.0, 100.0])
    f1 = np.array([99.0, 99.0, 99.0, 100.0 - 1e-9, 99.0])
    f2 = np.array([99.5, 98.1, 98.5, 100.0 - 2e-9, 99.0])  # rising again; ratio 0.9; 0.5; converged; flat
    lim, ratio, status = aitken(f0, f1, f2)
    assert list(status) == ["not asymptotic", "not asymptotic", "extrapolated", "converged", "converged"]
    assert lim[0] == f2[0] and lim[1] == f2[1] and lim[3] == f2[3]  # the finest value where no limit is taken
    assert lim[2] == pytest.approx(98.0)
    # the weights of the limit: finest value where no limit is taken, even at r = 1, silently
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w = aitken_weights(np.array([1.0, 0.5, np.nan]), np.array(["not asymptotic", "extrapolated", "converged"]))
    np.testing.assert_allclose(w, [[0, 0, 1], [1, -4, 4], [0, 0, 1]])


@settings(max_examples=100, deadline=None)
@given(limit=st.floats(50.0, 5000.0), drop=st.floats(1e-4, 0.05), r=st.floats(0.05, 0.79))
def test_a_given_ratio_recovers_the_limit_from_two_meshes(limit, drop, r):
    f0, f1 = (limit * (1 + drop * r**k) for k in range(2))
    lim, ratio, status = geometric_limit(np.array([f0]), np.array([f1]), r)
    assert status[0] == "extrapolated" and ratio[0] == r
    assert lim[0] == pytest.approx(limit, rel=1e-9)


def test_a_given_ratio_refuses_a_rising_mode_and_its_weights_are_the_derivatives():
    f0, f1 = np.array([100.0, 100.0, 100.0]), np.array([99.0, 100.5, 100.0 - 1e-9])
    lim, ratio, status = geometric_limit(f0, f1, 0.45)
    assert list(status) == ["extrapolated", "not asymptotic", "converged"]
    assert lim[0] == pytest.approx(99.0 - 0.45 / 0.55) and lim[1] == 100.5 and lim[2] == f1[2]
    w = aitken_weights(ratio, status, n_levels=2)
    h = 1e-6  # the weights are d lim / d (f0, f1): central differences of the limit
    num = [(geometric_limit(f0 + h * (k == 0), f1 + h * (k == 1), 0.45)[0][0]
            - geometric_limit(f0 - h * (k == 0), f1 - h * (k == 1), 0.45)[0][0]) / (2 * h) for k in range(2)]
    np.testing.assert_allclose(w[0], num, rtol=1e-6)
    np.testing.assert_allclose(w[1:], [[0, 1], [0, 1]])
    # edge_limit on two meshes with the ratio given: the same limits, and two meshes without one refused
    rng = np.random.default_rng(5)
    s = _shapes(rng, 12, 3)
    solves = [(f0, s, 100), (f1, s, 200)]
    np.testing.assert_allclose(edge_limit(solves, ratio=0.45).limit_Hz, lim)
    with pytest.raises(ValueError, match="needs 3 meshes, got 2"):
        edge_limit(solves)


def _shapes(rng, n_labels, n_modes):
    q, _ = np.linalg.qr(rng.standard_normal((n_labels, n_modes)))
    return q


def test_edge_limit_follows_modes_that_swap_order_between_meshes():
    rng = np.random.default_rng(3)
    s = _shapes(rng, 30, 5)
    limit = np.array([300.0, 1000.0, 1020.0, 2000.0, 3000.0])
    drop = np.array([0.001, 0.03, 0.001, 0.01, 0.02])
    r = 0.5
    freqs = [limit * (1 + drop * r**k) for k in range(3)]  # modes 2 and 3 swap order after the base mesh
    perm = [np.argsort(f) for f in freqs]
    assert not np.array_equal(perm[0], perm[2])
    solves = [(f[p], (s + (0.01 * k) * rng.standard_normal(s.shape))[:, p], 100 * (k + 1))
              for k, (f, p) in enumerate(zip(freqs, perm))]
    # a sixth mode on the finer meshes only (they are solved for more modes)
    extra = _shapes(rng, 30, 1)
    solves = [solves[0]] + [(np.append(f, 4000.0), np.hstack([sh, extra]), n) for f, sh, n in solves[1:]]
    lim = edge_limit(solves)
    assert lim.status == ["extrapolated"] * 5
    np.testing.assert_allclose(lim.limit_Hz, limit[perm[0]], rtol=1e-9)
    np.testing.assert_allclose(lim.levels_Hz, np.array(freqs)[:, perm[0]], rtol=1e-12)
    np.testing.assert_allclose(lim.factor, limit[perm[0]] / freqs[0][perm[0]])
    assert lim.n_dofs == [100, 200, 300]


def test_edge_limit_keeps_the_base_frequency_of_a_mode_it_cannot_follow():
    rng = np.random.default_rng(4)
    s = _shapes(rng, 20, 3)
    other = _shapes(rng, 20, 3)
    s2 = s.copy()
    s2[:, 1] = other[:, 2] - (s[:, [0, 2]] @ (s[:, [0, 2]].T @ other[:, 2]))  # mode 2 has no partner
    solves = [(np.array([100.0, 200, 300]), s, 1), (np.array([99.0, 199, 299]), s2, 2), (np.array([98.5, 198, 298.5]), s2, 3)]
    lim = edge_limit(solves)
    assert lim.status[1] == "lost" and lim.limit_Hz[1] == 200.0
    assert lim.status[0] == "extrapolated" and lim.limit_Hz[0] == pytest.approx(98.0)


def test_correction_stays_with_its_mode_and_keeps_the_sensitivities():
    rng = np.random.default_rng(5)
    n_dofs, n = 12, 4
    shapes = _shapes(rng, 15, n)
    factor = np.array([0.999, 0.98, 1.0, 0.995])
    corr = FrequencyCorrection(shapes, factor)
    perm = np.array([2, 0, 3, 1])
    np.testing.assert_allclose(corr.factors(shapes[:, perm])[0], factor[perm])
    unknown = _shapes(rng, 15, 1)
    np.testing.assert_allclose(corr.factors(np.hstack([shapes, unknown]))[0][-1], 1.0)

    # two close modes whose order the factors swap: the corrected solve returns them sorted
    freqs = np.array([300.0, 1000.0, 1010.0, 2000.0])
    factor = np.array([1.0, 1.0, 0.98, 1.0])
    phi = rng.standard_normal((n_dofs, n))
    Kt = rng.standard_normal((n_dofs, n_dofs))
    stiff = {"K_t": Kt @ Kt.T}
    solve = _corrected(lambda theta: (freqs, shapes, phi, stiff), FrequencyCorrection(shapes, factor))
    f_c, s_c, phi_c, _ = solve(np.array([1.0]))
    np.testing.assert_allclose(f_c, [300.0, 989.8, 1000.0, 2000.0])
    np.testing.assert_allclose(s_c, shapes[:, [0, 2, 1, 3]])
    # d ln f / d log10 theta is the same for the corrected frequencies as for the mesh's
    J_mesh = log_jacobian(stiff, phi, (2 * np.pi * freqs) ** 2, [{"K_t": 1.0}], np.array([2.0]))
    J_corr = log_jacobian(stiff, phi_c, (2 * np.pi * f_c) ** 2, [{"K_t": 1.0}], np.array([2.0]))
    np.testing.assert_allclose(J_corr[:, 0], J_mesh[[0, 2, 1, 3], 0], rtol=1e-12)


def test_with_edge_levels_adds_levels_to_the_configured_ones():
    from pathlib import Path

    from jointid.config import load_config
    from jointid.config.typed import ModelSpec

    spec = ModelSpec.from_config(load_config(Path(__file__).resolve().parents[1] / "config.yaml",
                                             overrides={"mesh": {"edge_refine_levels": 1}}))
    assert spec.with_edge_levels(2).mesh.edge_refine_levels == 3
    assert spec.mesh.edge_refine_levels == 1  # frozen: the spec itself is unchanged
    assert spec.with_edge_levels(0) is spec
    assert spec.with_edge_levels(2).joints is spec.joints


def test_an_edge_level_solved_once_finds_its_ordering_in_its_one_factorisation(monkeypatch):
    """The edge levels the extrapolation builds are each solved once: no separate ordering step (4.5 s on the
    default mesh's +1 level, for 1 s less in its one factorisation).  The run's own model (rule mesh) keeps
    one, for the many factorisations of later jobs."""
    from types import SimpleNamespace

    from jointid.fe import modal
    from jointid.fe import model as fe_model

    spec = SimpleNamespace(with_edge_levels=lambda k: ("levels", k), mesh=SimpleNamespace(edge_extra_levels=(1, 2)))
    monkeypatch.setattr(fe_model, "build_model", lambda s, progress=None: SimpleNamespace(built=s))
    monkeypatch.setattr(modal, "model_ordering", lambda m: "an ordering")
    built = [build() for build in fe_model.edge_level_builders(spec)]
    assert [m.built for m in built] == [("levels", 1), ("levels", 2)]
    assert all(m.ordering is None for m in built)
    assert fe_model.edge_level_model(spec, 0).ordering == "an ordering"


def test_extrapolated_cantilever_is_closer_to_the_converged_frequency_than_the_finest_mesh():
    """A cantilever bonded to a clamped wall block: its root edges are singular, and each root-edge
    level moves the frequencies by about half the previous level's change.  The Aitken limit of
    levels 0-2 lies far closer to that of levels 2-4 (a better estimate of the converged value) than
    level 2 itself does."""
    f = np.array([_cantilever_freqs(k) for k in range(5)])
    lim_012, ratio, status = aitken(*f[:3])
    lim_234, _, _ = aitken(*f[2:])
    assert set(status) == {"extrapolated"} and np.all((ratio > 0.3) & (ratio < 0.6))
    err_lim = np.abs(lim_012 / lim_234 - 1)
    err_raw = np.abs(f[2] / lim_234 - 1)
    assert np.all(err_lim < 0.5 * err_raw)
    assert np.median(err_raw / err_lim) > 4


def test_factor_slope_matches_the_limit_of_parameter_dependent_sequences():
    """Sequences f_k(y) = L e^{b y} (1 + d e^{e y} r^k) for two parameters y: the limit's factor
    1 / (1 + d e^{e y}) and its exact derivative; edge_limit gets it from the meshes' sensitivities."""
    rng = np.random.default_rng(6)
    s = _shapes(rng, 20, 3)
    L, r = np.array([300.0, 1400.0, 2600.0]), np.array([0.45, 0.47, 0.5])
    b = np.array([[0.05, 0.0], [0.2, 0.4], [0.3, 0.1]])
    d, e = np.array([0.002, 0.02, 0.01]), np.array([[0.1, 0.0], [-0.5, 0.8], [0.2, -0.3]])
    y = np.array([0.1, -0.2])

    def level(k):
        g = d * np.exp(e @ y) * r**k
        f = L * np.exp(b @ y) * (1 + g)
        J = b + (g / (1 + g))[:, None] * e  # d ln f_k / dy
        return f, s, 10 * (k + 1), J

    lim = edge_limit([level(k) for k in range(3)])
    g0 = d * np.exp(e @ y)
    np.testing.assert_allclose(lim.factor, 1 / (1 + g0), rtol=1e-9)
    np.testing.assert_allclose(lim.slope, -(g0 / (1 + g0))[:, None] * e, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(aitken_weights(lim.ratio, lim.status).sum(axis=1), 1.0)

    corr = FrequencyCorrection.from_limit(lim, theta_ref=10**y)
    y2 = y + np.array([0.03, -0.02])
    c, grad = corr.factors(s[:, ::-1], 10**y2)
    np.testing.assert_allclose(grad, lim.slope[::-1])
    g2 = d * np.exp(e @ y2)
    np.testing.assert_allclose(c, (1 / (1 + g2))[::-1], rtol=1e-5)  # first order in a 0.03-decade step
