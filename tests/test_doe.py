"""Tests of jointid.identification.doe: design sizes, coding, determinism, size checks."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointid.config.options import DoeOptions
from jointid.identification import doe
from jointid.errors import ConfigError
from jointid.identification.surface import quadratic_basis


@pytest.mark.parametrize("k, n_center, n_expected", [(2, 1, 9), (3, 1, 15), (2, 3, 11), (4, 0, 24)])
def test_ccf_size_and_levels(k, n_center, n_expected):
    X = doe.design("ccf", k, n_center=n_center)
    assert X.shape == (n_expected, k)
    assert np.all(np.abs(X) <= 1.0)
    # three levels only, all corners present, 2k axial points, n_center centre points
    assert set(np.unique(X)) <= {-1.0, 0.0, 1.0}
    rows = {tuple(r) for r in X}
    assert all(c in rows for c in itertools.product((-1.0, 1.0), repeat=k))
    n_axial = sum(1 for r in X if np.count_nonzero(r) == 1 and np.abs(r).sum() == 1.0)
    assert n_axial == 2 * k
    assert sum(1 for r in X if not np.any(r)) == n_center


@pytest.mark.parametrize("kind, k", [("ccf", 2), ("ccf", 3), ("box_behnken", 3), ("box_behnken", 4)])
def test_designs_support_full_quadratic(kind, k):
    X = doe.design(kind, k, n_center=1)
    A = quadratic_basis(X)
    assert np.linalg.matrix_rank(A) == doe.n_quadratic_terms(k)


def test_box_behnken_sizes():
    for nc in (0, 1, 3):
        X = doe.design("box_behnken", 3, n_center=nc)
        assert X.shape == (12 + nc, 3)
        assert np.all(np.abs(X) <= 1.0)
    # every non-centre run has exactly two factors at +-1
    X = doe.design("box_behnken", 4, n_center=0)
    assert X.shape == (24, 4)
    assert np.all(np.count_nonzero(X, axis=1) == 2)


def test_box_behnken_two_factors_points_to_ccf():
    with pytest.raises(ConfigError, match="use kind: ccf"):
        doe.design("box_behnken", 2)


def test_unknown_kind_and_missing_samples_are_config_errors():
    with pytest.raises(ConfigError, match="unknown design"):
        doe.design("full_factorial", 2)
    with pytest.raises(ConfigError, match="n_samples"):
        doe.design("lhs", 2, n_samples=0)


def test_lhs_deterministic_stratified_with_centre():
    a = doe.design("lhs", 3, n_samples=20, seed=7)
    b = doe.design("lhs", 3, n_samples=20, seed=7)
    c = doe.design("lhs", 3, n_samples=20, seed=8)
    assert a.shape == (21, 3)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_array_equal(a[-1], np.zeros(3))
    assert np.all(np.abs(a) <= 1.0)
    # Latin property: each of the 20 strata of every column holds exactly one sample
    strata = np.floor((a[:-1] + 1.0) / 2.0 * 20).astype(int)
    for j in range(3):
        assert sorted(strata[:, j]) == list(range(20))


@pytest.mark.parametrize("n, d, seed", [(1, 1, 0), (7, 3, 20191), (40, 2, 5), (17, 5, 123)])
def test_latin_hypercube_draws_scipys_points_bit_for_bit(n, d, seed):
    import scipy
    from scipy.stats import qmc

    if tuple(int(v) for v in scipy.__version__.split(".")[:2]) < (1, 15):
        pytest.skip("SciPy < 1.15 draws its Latin hypercube from the generator itself, not a spawned child")
    ref = qmc.LatinHypercube(d=d, rng=np.random.default_rng(seed)).random(n)
    ours = doe.latin_hypercube(n, d, np.random.default_rng(seed))
    assert np.array_equal(ours, ref)
    assert np.array_equal(np.sort(np.floor(ours * n), axis=0), np.tile(np.arange(n)[:, None], (1, d)))  # one per stratum


def test_n_quadratic_terms():
    assert [doe.n_quadratic_terms(k) for k in (1, 2, 3, 4)] == [3, 6, 10, 15]


def test_check_design_size_message():
    doe.check_design_size(10, 3)  # exactly enough: no error
    with pytest.raises(ConfigError) as err:
        doe.check_design_size(8, 3)
    msg = str(err.value)
    assert "DOE has 8 points but a full quadratic in 3 factors needs 10" in msg
    assert "use ccf or raise doe.n_samples to >= 20" in msg


def test_to_physical_anchor_points():
    lo, hi = np.array([1e10, 1e3]), np.array([1e12, 4e3])
    P = doe.to_physical(np.array([[-1.0, -1.0], [1.0, 1.0], [0.0, 0.0]]), lo, hi)
    np.testing.assert_allclose(P[0], lo, rtol=1e-12)
    np.testing.assert_allclose(P[1], hi, rtol=1e-12)
    np.testing.assert_allclose(P[2], np.sqrt(lo * hi), rtol=1e-12)


def test_bad_bounds_are_reported_together():
    with pytest.raises(ConfigError) as err:
        doe.to_physical(np.zeros(2), [1.0, -1.0], [0.5, 2.0])
    assert len(err.value.problems) == 2


@settings(max_examples=60, deadline=None)
@given(
    lo_exp=st.lists(st.floats(-3, 12), min_size=1, max_size=4),
    span=st.floats(0.01, 6.0),
    u=st.floats(-1.0, 1.0),
)
def test_coding_round_trip(lo_exp, span, u):
    lo = 10.0 ** np.array(lo_exp)
    hi = lo * 10.0**span
    k = lo.size
    x = np.linspace(-1.0, 1.0, 3 * k).reshape(3, k) * u
    theta = doe.to_physical(x, lo, hi)
    assert np.all(theta >= lo * (1 - 1e-12)) and np.all(theta <= hi * (1 + 1e-12))
    np.testing.assert_allclose(doe.to_coded(theta, lo, hi), x, atol=1e-9)
    np.testing.assert_allclose(doe.to_physical(doe.to_coded(theta, lo, hi), lo, hi), theta,
                               rtol=1e-9)


def test_verification_points_fresh_and_interior():
    V = doe.verification_points(12, 3, seed=0)
    assert V.shape == (12, 3)
    assert np.all(np.abs(V) <= 0.9)
    np.testing.assert_array_equal(V, doe.verification_points(12, 3, seed=0))
    D = doe.design("lhs", 3, n_samples=12, seed=0)[:-1]
    assert not np.allclose(0.9 * D, V)  # a different random stream from the design's


# ------------------------------------------------------------------ the zoomed second DOE
def _zoom_cfg(w=0.15):
    from conftest import coarse_config_dict

    cfg = coarse_config_dict()
    cfg["doe"]["zoom"] = {"enabled": True, "half_width_decades": w}
    return DoeOptions.from_config(cfg)


def test_zoom_box_spans_all_state_optima_with_the_margin():
    from jointid.stages.doe import zoom_box

    cfg = _zoom_cfg(0.15)
    optima = {"a": {"k_normal_N_per_m3": 3e11, "k_lateral_N_per_m3": 1.2e12, "k_feed_N_per_m3": 8e9},
              "b": {"k_normal_N_per_m3": 5e11, "k_lateral_N_per_m3": 1.5e12, "k_feed_N_per_m3": 8e9}}
    lo, hi = zoom_box(cfg, optima)
    f = 10 ** 0.15
    np.testing.assert_allclose(lo, [3e11 / f, 1.2e12 / f, 8e9 / f], rtol=1e-12)
    np.testing.assert_allclose(hi, [5e11 * f, 1.5e12 * f, 8e9 * f], rtol=1e-12)


def test_zoom_box_at_a_bound_keeps_its_width_inside_the_bounds():
    from jointid.stages.doe import zoom_box

    cfg = _zoom_cfg(0.2)
    b_lo, b_hi = cfg.joints.lower_N_per_m3, cfg.joints.upper_N_per_m3
    optima = {"a": {"k_normal_N_per_m3": b_lo[0], "k_lateral_N_per_m3": b_hi[1], "k_feed_N_per_m3": 1e10}}
    lo, hi = zoom_box(cfg, optima)
    assert np.all(lo >= b_lo * (1 - 1e-12)) and np.all(hi <= b_hi * (1 + 1e-12))
    np.testing.assert_allclose(np.log10(hi / lo), 0.4, rtol=1e-9)  # full width 2 w everywhere
    np.testing.assert_allclose([lo[0], hi[1]], [b_lo[0], b_hi[1]], rtol=1e-12)


def test_zoom_box_wider_than_the_bounds_is_the_bounds():
    from jointid.stages.doe import zoom_box

    cfg = _zoom_cfg(1.0)
    lo, hi = zoom_box(cfg, {"a": {"k_normal_N_per_m3": 1e12, "k_lateral_N_per_m3": 1e12, "k_feed_N_per_m3": 1e10}})
    np.testing.assert_allclose(lo, cfg.joints.lower_N_per_m3, rtol=1e-12)
    np.testing.assert_allclose(hi, cfg.joints.upper_N_per_m3, rtol=1e-12)


def test_zoomed_sheet_codes_its_own_box():
    from jointid.stages.doe import doe_sheet

    cfg = _zoom_cfg()
    names = cfg.joints.names
    lo, hi = np.array([2e11, 8e11, 6e9]), np.array([7e11, 2e12, 1.2e10])
    zoom, full = doe_sheet(cfg, lo, hi), doe_sheet(cfg)
    assert list(zoom.point) == list(full.point) and list(zoom.role) == list(full.role)
    X = zoom[[f"x_{n}" for n in names]].to_numpy()
    np.testing.assert_array_equal(X, full[[f"x_{n}" for n in names]].to_numpy())  # same coded design
    theta = zoom[names].to_numpy()
    np.testing.assert_allclose(theta, doe.to_physical(X, lo, hi), rtol=1e-12)
    assert np.all(theta >= lo * (1 - 1e-12)) and np.all(theta <= hi * (1 + 1e-12))
