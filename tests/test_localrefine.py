"""Local refinement at re-entrant edges: hanging-node constraints, nestedness, the rig model on it."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementHex1, ElementHex2

from jointid.fe import fem
from jointid.geometry import localrefine
from jointid.fe.modal import solve_modes
from jointid.config.typed import ModelSpec


def _boxes_with_hanging_nodes():
    """Two unit cubes side by side; the left one split in eight, one of its octants split again
    (its small cells meet the right cube: a jump of two levels across a face)."""
    lo = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    hi = np.array([[1.0, 1, 1], [2.0, 1, 1]])
    body = np.array([0, 0])
    lo, hi, body = localrefine.split(lo, hi, np.array([True, False]), body)
    corner = np.flatnonzero(np.all(np.isclose(hi, [1.0, 1.0, 1.0]), axis=1) & (lo[:, 0] > 0.4))
    mask = np.zeros(len(lo), bool)
    mask[corner] = True
    return localrefine.split(lo, hi, mask, body)


@pytest.mark.parametrize("elem, order", [(ElementHex2, 2), (ElementHex1, 1)])
def test_constraints_reproduce_polynomials_of_the_element(elem, order):
    lo, hi, body = _boxes_with_hanging_nodes()
    basis = Basis(localrefine.box_mesh(lo, hi, body), elem())
    T, free = localrefine.hanging_constraints(basis.doflocs, basis.element_dofs, lo, hi, body, order)
    assert T.shape == (basis.N, len(free)) and len(free) < basis.N  # some nodes hang
    x, y, z = basis.doflocs
    if order == 2:
        f = lambda x, y, z: 1 + x - 2 * y + z + x * y - 0.5 * z * x + y * y - 3 * z * z  # noqa: E731
    else:
        f = lambda x, y, z: 1 + x - 2 * y + 3 * z  # noqa: E731
    assert np.abs(T @ f(*basis.doflocs[:, free]) - f(x, y, z)).max() < 1e-12


def test_constrained_field_is_continuous_across_non_conforming_faces():
    lo, hi, body = _boxes_with_hanging_nodes()
    basis = Basis(localrefine.box_mesh(lo, hi, body), ElementHex2())
    T, free = localrefine.hanging_constraints(basis.doflocs, basis.element_dofs, lo, hi, body, 2)
    u = T @ np.random.default_rng(3).standard_normal(len(free))
    rng = np.random.default_rng(4)
    yz = rng.uniform(0.02, 0.98, (40, 2))
    on_face = np.column_stack([np.ones(40), yz])  # the face x = 1 between the fine and the coarse cells
    left = basis.probes((on_face - [1e-9, 0, 0]).T) @ u
    right = basis.probes((on_face + [1e-9, 0, 0]).T) @ u
    assert np.abs(left - right).max() < 1e-6 * np.abs(u).max()
    # without the constraints the raw field jumps there
    raw = rng.standard_normal(basis.N)
    jump = basis.probes((on_face - [1e-9, 0, 0]).T) @ raw - basis.probes((on_face + [1e-9, 0, 0]).T) @ raw
    assert np.abs(jump).max() > 1e-2


def test_reentrant_edges_of_an_l_shape_and_clipping():
    # 2 x 2 cells in X-Y (one Z layer), the upper-right one void: one re-entrant edge along Z at (1, 1)
    lines = (np.array([0.0, 1, 2]), np.array([0.0, 1, 2]), np.array([0.0, 3]))
    group = np.array([[[0], [0]], [[0], [-1]]])
    segs = localrefine.reentrant_segments(lines, group)
    assert len(segs[0]) == len(segs[1]) == 0
    assert np.allclose(segs[2], [[1.0, 1.0, 0.0, 3.0]])
    # two groups (bodies joined only by joint springs) make no re-entrant edge of either
    assert sum(len(s) for s in localrefine.reentrant_segments(lines, np.array([[[0], [1]], [[0], [-1]]]))) == 0
    clipped = localrefine.clip_segments(segs, np.array([0.0, 0, 1]), np.array([2.0, 2, 2]))
    assert np.allclose(clipped[2], [[1.0, 1.0, 1.0, 2.0]])


def test_refinement_cuts_across_the_edge_only():
    lo, hi = np.array([[0.0, 0, 0]]), np.array([[1.0, 1, 4]])
    segs = [np.zeros((0, 4)), np.zeros((0, 4)), np.array([[0.0, 0.0, 0.0, 4.0]])]  # along Z at x = y = 0
    level = np.zeros(1, int)
    for _ in range(2):
        lo, hi, level = localrefine.refine_at(lo, hi, segs, level)
    lo2, hi2 = lo, hi
    size = hi2 - lo2
    assert np.allclose(size[:, 2], 4.0)  # never cut along the edge
    assert np.isclose(size[:, 0].min(), 0.25) and np.isclose(np.prod(size, axis=1).sum(), 4.0)
    assert len(lo2) == 4 + 3  # 4 quarters, the one at the edge cut again


def _cantilever_freqs(levels, n=6, elem=ElementHex2, order=2):
    """A 0.4 x 0.04 x 0.04 m steel cantilever on a 0.1 m-wide clamped wall block; the re-entrant edges
    at the root refined ``levels`` times (``levels=None``: every cell halved)."""
    xs, ys, zs = np.linspace(0, 0.4, 11), np.array([0.0, 0.02, 0.04]), np.array([0.0, 0.02, 0.04])
    lo = np.stack(np.meshgrid(xs[:-1], ys[:-1], zs[:-1], indexing="ij"), -1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(xs[1:], ys[1:], zs[1:], indexing="ij"), -1).reshape(-1, 3)
    wall_lo = np.array([[-0.04, -0.04, -0.04]]) + np.array([[0, 0.04 * i, 0.04 * j] for i in range(3) for j in range(3)])
    lo = np.vstack([lo, wall_lo])
    hi = np.vstack([hi, wall_lo + 0.04])
    wall = np.arange(len(lo)) >= len(lo) - 9
    body = np.zeros(len(lo), int)
    if levels is None:
        lo, hi, wall = localrefine.split(lo, hi, np.ones(len(lo), bool), wall)
    elif levels:
        segs = [np.zeros((0, 4)),
                np.array([[0.0, 0.0, 0.0, 0.04], [0.0, 0.04, 0.0, 0.04]]),
                np.array([[0.0, 0.0, 0.0, 0.04], [0.0, 0.04, 0.0, 0.04]])]
        level = np.zeros(len(lo), int)
        for _ in range(levels):
            lo, hi, level, wall = localrefine.refine_at(lo, hi, segs, level, wall)
    body = np.zeros(len(lo), int)
    basis = Basis(localrefine.box_mesh(lo, hi, body), elem(), intorder=2 * order)
    lam, mu = fem.lame(2.06e11, 0.3)
    ne = len(lo)
    K, M = fem.assemble_elasticity(basis, np.full(ne, lam), np.full(ne, mu), np.full(ne, 7850.0))
    T, free = localrefine.hanging_constraints(basis.doflocs, basis.element_dofs, lo, hi, body, order)
    Tv = sp.kron(T, sp.eye(3), format="csr")
    locs = basis.doflocs[:, free]
    clamp = np.flatnonzero(locs[0] < -0.04 + 1e-9)
    fixed = np.sort(np.concatenate([3 * clamp + c for c in range(3)]))
    modes = solve_modes((Tv.T @ K @ Tv).tocsr(), (Tv.T @ M @ Tv).tocsr(), n, shift_Hz=-1.0, fixed=fixed)
    return modes.freqs_Hz


def test_local_refinement_is_sandwiched_between_the_coarse_and_the_halved_mesh():
    """The locally refined space contains the coarse one and lies inside the uniformly halved one, so
    by the min-max principle each frequency lies between theirs; and it moves towards the beam."""
    coarse = _cantilever_freqs(0)
    local = _cantilever_freqs(1)
    halved = _cantilever_freqs(None)
    assert np.all(local <= coarse * (1 + 1e-9)) and np.all(local >= halved * (1 - 1e-9))
    assert np.any(local < coarse * (1 - 1e-4))
    # Euler-Bernoulli first bending of the 0.4 m square cantilever, 1.875^2 sqrt(EI / (rho A)) / (2 pi L^2)
    a, L = 0.04, 0.4
    f1 = 1.8751**2 / (2 * np.pi * L**2) * np.sqrt(2.06e11 * a**4 / 12 / (7850.0 * a * a))
    assert abs(local[0] / f1 - 1) < 0.05


def test_rig_model_on_the_locally_refined_mesh(tmp_path):
    from jointid.fe.model import base_coefficients, build_model, load_model, save_model

    from conftest import coarse_config_dict

    cfg = coarse_config_dict()
    ref = build_model(ModelSpec.from_config(cfg))
    cfg["mesh"]["edge_refine_levels"] = 1
    model = build_model(ModelSpec.from_config(cfg))
    assert model.n_dofs > ref.n_dofs
    # the same contact faces and the same solid mass: areas and rigid-body mass are mesh-independent
    for face in ("top", "flank"):
        assert np.isclose(model.meta["contact_area_m2"][face], ref.meta["contact_area_m2"][face], rtol=1e-10)
    ones = np.zeros(model.n_dofs)
    ones[0::3] = 1.0
    ones_ref = np.zeros(ref.n_dofs)
    ones_ref[0::3] = 1.0
    assert np.isclose(ones @ model.mass["M0"] @ ones, ones_ref @ ref.mass["M0"] @ ones_ref, rtol=1e-10)
    # a rigid translation of everything strains no solid and stretches no joint
    for name in ("K0", "K_top_y", "K_flank_x", "K_railfix"):
        assert np.abs(model.stiffness[name] @ ones).max() < 1e-6 * abs(model.stiffness[name]).max()
    # the clamped base bottom: exactly the free nodes there are fixed (some hang on coarser faces)
    bottom = np.flatnonzero((model.doflocs[1] < 1e-9) & (model.dof_part == 0))
    assert np.array_equal(np.unique(model.fixed // 3), bottom)
    # nested space: no frequency rises
    freqs = []
    for m in (ref, model):
        kc, mc = base_coefficients(ModelSpec.from_config(cfg), m)
        modes = solve_modes(m.K(kc), m.M(mc), 10, shift_Hz=-10.0, fixed=m.fixed)
        freqs.append(modes.freqs_Hz)
    assert np.all(freqs[1] <= freqs[0] * (1 + 1e-8)) and np.any(freqs[1] < freqs[0] * (1 - 1e-4))
    # the cache keeps the map from the free DOFs back to the mesh vertices; the VTK export uses it
    save_model(model, tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    assert back.n_dofs == model.n_dofs and "vertex_indptr" in back.meta["mesh"]
    import meshio

    from jointid.fe.vtk import write_mesh_vtu

    write_mesh_vtu(back, tmp_path / "m.vtu", modes=modes.phi[:, :2], freqs_Hz=modes.freqs_Hz[:2])
    vtu = meshio.read(tmp_path / "m.vtu")
    assert np.allclose(vtu.field_data["freq_Hz"], modes.freqs_Hz[:2], rtol=1e-15)  # the frequencies too
    u = next(v for k, v in vtu.point_data.items() if k.startswith("mode_01"))
    mesh = back.meta["mesh"]
    Tv = sp.csr_matrix((mesh["vertex_data"], mesh["vertex_indices"], mesh["vertex_indptr"]),
                       shape=(mesh["p"].shape[1], back.n_dofs // 3))
    single = np.flatnonzero((np.diff(Tv.indptr) == 1) & np.isclose(Tv.sum(axis=1).A1, 1.0))
    assert len(single) > 0 and np.all(np.isfinite(u))
    phi = modes.phi[:, 0].reshape(-1, 3)
    assert np.allclose(u[single], phi[Tv.indices[Tv.indptr[single]]], atol=1e-12 * np.abs(phi).max())


def test_edges_class_adds_one_nested_level():
    from jointid.config import load_config
    from jointid.config.typed import MeshOptions
    from jointid.geometry.mesh import mesh_from_config
    from jointid.geometry.rig import build_rig

    from conftest import REPO

    cfg = load_config(REPO / "config.yaml")
    rig = build_rig(cfg["rig"])
    one = mesh_from_config(rig, MeshOptions.from_section(dict(cfg["mesh"], edge_refine_levels=1)))
    two = mesh_from_config(rig, MeshOptions.from_section(dict(cfg["mesh"], edge_refine_levels=1)), halve=("edges",))
    assert (two.boxes[0].shape[0] > one.boxes[0].shape[0]
            and np.array_equal(two.boxes[0], mesh_from_config(rig, MeshOptions.from_section(dict(cfg["mesh"], edge_refine_levels=2))).boxes[0]))
    # nested: every cell of the finer mesh lies inside one cell of the coarser
    (lo1, hi1), (lo2, hi2) = one.boxes, two.boxes
    c2 = 0.5 * (lo2 + hi2)
    for found, lo, hi in zip(localrefine.boxes_at(lo1, hi1, c2), lo2, hi2):
        assert len(found) == 1
        assert np.all(lo >= lo1[found[0]] - 1e-12) and np.all(hi <= hi1[found[0]] + 1e-12)
