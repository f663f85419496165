"""Hammer-tip patch (jointid.fe.patch): the disc quadrature, the patch rows, and the drive-point
flexibility under mesh refinement (a point load's local flexibility grows without bound)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import yaml

from jointid.config import load_config
from jointid.fe.modal import factorize, free_dofs, restrict
from jointid.fe.model import base_coefficients, build_model
from jointid.fe.patch import disc_points, patch_probe
from jointid.config.typed import ModelSpec

from conftest import COARSE_CONFIG, REPO


def test_disc_quadrature_is_the_mean_over_the_disc():
    xz, w = disc_points([0.1, -0.2], 0.010)
    assert w.sum() == pytest.approx(1.0, rel=1e-14)
    r2 = (xz[0] - 0.1) ** 2 + (xz[1] + 0.2) ** 2
    assert np.sqrt(r2.max()) < 0.005
    assert w @ r2 == pytest.approx(0.005**2 / 2, rel=1e-12)  # mean of r^2 over a disc of radius a: a^2 / 2
    assert w @ (r2**3) == pytest.approx(0.005**6 / 4, rel=1e-12)  # of r^6: a^6 / 4
    assert w @ (xz[0] - 0.1) == pytest.approx(0.0, abs=1e-18)


@pytest.fixture(scope="module")
def coarse_cfg():
    return load_config(REPO / "config.yaml", overrides=yaml.safe_load(COARSE_CONFIG.read_text()))


def _flexibility(cfg, halve, diameter_m, points=("T05", "T08")):
    """Static drive-point flexibility in Y (m/N) at ``points`` with a patch of ``diameter_m``."""
    m = build_model(ModelSpec.from_config(cfg), halve=halve)
    kc, _ = base_coefficients(ModelSpec.from_config(cfg), m)
    K = m.K(kc)
    free = free_dofs(K.shape[0], m.fixed)
    fac = factorize(restrict(sp.csr_matrix(K), free), "auto")
    try:
        P = np.asarray(patch_probe(m, list(points), diameter_m)[1::3][:, free].toarray())
        return np.array([P[k] @ np.asarray(fac.solve(P[k])).ravel() for k in range(len(points))]), m
    finally:
        fac.free()


def test_patch_rows_reduce_to_the_probe_and_sum_to_one(coarse_cfg):
    m = build_model(ModelSpec.from_config(coarse_cfg))
    names = ["T01", "T05", "T18"]
    rows = np.concatenate([[3 * i + c for c in range(3)] for i in (0, 4, 17)])
    assert abs(patch_probe(m, names, 0.0) - m.probe[rows]).max() == 0.0
    tiny = patch_probe(m, names, 1e-5)  # a disc far inside one element: its shape-function means are the point values
    assert abs(tiny - m.probe[rows]).max() < 1e-6
    P = patch_probe(m, names, 0.010)
    np.testing.assert_allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0, rtol=1e-12)
    assert P[4].nnz >= m.probe[rows][4].nnz  # the y row of T05: the disc reaches at least the point's nodes


def test_patch_flexibility_changes_less_under_refinement_than_a_point_load(coarse_cfg):
    """Coarse test mesh and the same mesh with its cells halved in plan (X, Z): the point load's local
    flexibility grows by about 30 %, the 10 mm patch's by less (it converges once the cells resolve it)."""
    point0, _ = _flexibility(coarse_cfg, (), 0.0)
    patch0, _ = _flexibility(coarse_cfg, (), 0.010)
    point1, _ = _flexibility(coarse_cfg, ("plan",), 0.0)
    patch1, _ = _flexibility(coarse_cfg, ("plan",), 0.010)
    d_point = point1 / point0 - 1
    d_patch = patch1 / patch0 - 1
    assert np.all(d_point > 0.1)  # refining softens a point load markedly
    assert np.all(np.abs(d_patch) < 0.8 * np.abs(d_point)), (d_point, d_patch)
