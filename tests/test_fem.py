"""FE core against analytic references: rigid block on a spring layer, Euler-Bernoulli beam, identities."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementHex2

from jointid.fe import fem
from jointid.geometry.mesh import build_mesh
from jointid.fe.modal import solve_modes
from jointid.geometry.rig import Box, Rig
from jointid.config.typed import ModelSpec


def _rig(boxes, top=(), flank=()):
    xs, ys, zs = set(), set(), set()
    for b in boxes:
        xs.update((b.lo[0], b.hi[0]))
        ys.update((b.lo[1], b.hi[1]))
        zs.update((b.lo[2], b.hi[2]))
    return Rig(boxes=list(boxes), contact={"top": list(top), "flank": list(flank)},
               patches={"motor": [], "mount": []}, carriage_centres=np.zeros((0, 3)),
               breakpoints=tuple(np.array(sorted(s)) for s in (xs, ys, zs)), materials={})


def _assemble(rmesh, E, rho, nu=0.3):
    basis = Basis(rmesh.mesh, ElementHex2(), intorder=4)
    lam, mu = fem.lame(E, nu)
    ne = rmesh.mesh.t.shape[1]
    K, M = fem.assemble_elasticity(basis, np.full(ne, lam), np.full(ne, mu), np.full(ne, rho))
    return basis, K, M


# block (body 1, "table") of L (z) x W (x) x h (y) on a clamped base (body 0) through a Y spring layer
L, W, h, hb = 0.20, 0.12, 0.05, 0.02
K_AREA = 1.0e11  # N/m^3


@pytest.fixture(scope="module")
def block_on_springs():
    boxes = [Box("table", (-W / 2, hb, -L / 2), (W / 2, hb + h, L / 2)),
             Box("base", (-W / 2, 0.0, -L / 2), (W / 2, hb, L / 2))]
    contact = [Box("top", (-W / 2, hb, -L / 2), (W / 2, hb, L / 2))]
    rmesh = build_mesh(_rig(boxes, top=contact), 0.05)
    basis, K, M = _assemble(rmesh, 1e16, 7850.0)  # (nearly) rigid solids
    S = fem.facet_mass(rmesh.mesh, ElementHex2(), rmesh.facets["top"], 4)
    Ky = fem.spring_layer(S, basis.doflocs, 1)
    fixed_s = basis.get_dofs(facets=rmesh.facets["bottom"]).all()
    fixed = np.sort(np.concatenate([3 * fixed_s + c for c in range(3)]))
    return dict(basis=basis, K=K, M=M, Ky=Ky, S=S, fixed=fixed, rmesh=rmesh)


def test_rigid_block_bounce_pitch_roll(block_on_springs):
    b = block_on_springs
    modes = solve_modes(b["K"] + K_AREA * b["Ky"], b["M"], 6, fixed=b["fixed"], shift_Hz=-1.0)
    m = 7850.0 * L * W * h
    bounce = np.sqrt(K_AREA * L * W / m) / (2 * np.pi)
    # rotation about the block's centroid (no tangential springs: no coupling with translation)
    pitch = np.sqrt(K_AREA * W * L**3 / 12 / (m * (L**2 + h**2) / 12)) / (2 * np.pi)
    roll = np.sqrt(K_AREA * L * W**3 / 12 / (m * (W**2 + h**2) / 12)) / (2 * np.pi)
    f = modes.freqs_Hz
    assert np.all(f[:3] < 1e-3 * bounce)  # free in x, z and yaw
    assert np.allclose(np.sort(f[3:]), np.sort([bounce, pitch, roll]), rtol=5e-3)


def test_eigenpairs_rayleigh_quotient_and_m_orthonormal(block_on_springs):
    b = block_on_springs
    K = b["K"] + K_AREA * b["Ky"]
    modes = solve_modes(K, b["M"], 6, fixed=b["fixed"], shift_Hz=-1.0)
    phi = modes.phi
    G = phi.T @ b["M"] @ phi
    assert np.allclose(G, np.eye(6), atol=1e-8)
    rq = np.einsum("ij,ij->j", phi, K @ phi)
    w2 = (2 * np.pi * modes.freqs_Hz) ** 2
    assert np.allclose(rq[3:], w2[3:], rtol=1e-8)


def test_joint_matrix_properties(block_on_springs):
    b = block_on_springs
    Ky = b["Ky"]
    assert abs(Ky - Ky.T).max() < 1e-12 * abs(Ky).max()
    # positive semi-definite: smallest eigenvalue of the dense matrix is ~0 from above
    ev = np.linalg.eigvalsh(Ky.toarray())
    assert ev.min() > -1e-9 * ev.max()
    # zero energy for a common rigid translation of both bodies, positive for a relative one
    n = Ky.shape[0]
    for d in range(3):
        u = np.zeros(n)
        u[d::3] = 1.0
        assert abs(u @ Ky @ u) < 1e-12 * abs(Ky).max()
    u = np.zeros(n)
    body1 = np.flatnonzero(b["basis"].doflocs[1] > hb - 1e-12)
    # lift only the nodes of body 1 (including its duplicated interface nodes)
    sel = np.unique(b["basis"].element_dofs[:, b["rmesh"].part == 3])
    u[3 * sel + 1] = 1e-6
    energy = u @ Ky @ u
    assert energy == pytest.approx(L * W * 1e-12, rel=1e-9)  # int (jump)^2 dA with unit stiffness
    assert len(body1) > 0


def test_joint_stiffness_is_exactly_affine(block_on_springs):
    b = block_on_springs
    K1 = b["K"] + 2.0e11 * b["Ky"]
    K2 = b["K"] + 5.0e11 * b["Ky"]
    K3 = b["K"] + 3.5e11 * b["Ky"]
    assert abs(0.5 * (K1 + K2) - K3).max() <= 1e-12 * abs(K3).max()


def test_beam_bending_matches_euler_bernoulli():
    Lb, hb_, wb = 1.0, 0.025, 0.025
    E, rho = 2.06e11, 7850.0
    rmesh = build_mesh(_rig([Box("base", (-wb / 2, 0.0, 0.0), (wb / 2, hb_, Lb))]), 0.05)
    basis, K, M = _assemble(rmesh, E, rho)
    clamped = basis.get_dofs(lambda x: np.isclose(x[2], 0.0)).all()
    fixed = np.sort(np.concatenate([3 * clamped + c for c in range(3)]))
    modes = solve_modes(K, M, 4, fixed=fixed, shift_Hz=-1.0)
    I = wb * hb_**3 / 12
    A = wb * hb_
    beta = np.array([1.8751040687, 4.6940911330])
    f_eb = beta**2 / (2 * np.pi * Lb**2) * np.sqrt(E * I / (rho * A))
    # square section: each bending frequency appears twice (bending in x and in y)
    f = modes.freqs_Hz
    assert np.allclose(f[[0, 1]], f_eb[0], rtol=0.01)
    assert np.allclose(f[[2, 3]], f_eb[1], rtol=0.01)


def test_vectorised_assembly_equals_scikit_fem_linear_elasticity():
    from skfem import ElementVector, asm
    from skfem.models.elasticity import linear_elasticity, lame_parameters

    rmesh = build_mesh(_rig([Box("base", (0.0, 0.0, 0.0), (0.1, 0.05, 0.2))]), 0.05)
    basis, K, M = _assemble(rmesh, 2.0e11, 7800.0)
    vb = Basis(rmesh.mesh, ElementVector(ElementHex2()), intorder=4)
    Kref = asm(linear_elasticity(*lame_parameters(2.0e11, 0.3)), vb)
    assert abs(K - Kref).max() < 1e-10 * abs(Kref).max()
    assert isinstance(K, sp.csr_matrix)


def test_interleaved_blocks_hold_the_bits_of_one_coo_conversion():
    """The shared-pattern interleave of the nine scalar blocks gives the matrix the general COO path gives,
    bit for bit (values, index arrays, their types); blocks of different patterns take the general path."""
    rng = np.random.default_rng(3)
    n = 40
    r, c = rng.integers(0, n, 600), rng.integers(0, n, 600)
    blocks = [[sp.csr_matrix((rng.standard_normal(600), (r, c)), shape=(n, n)) for _ in range(3)] for _ in range(3)]
    blocks[1][2].data[:5] = 0.0  # explicit zeros stay
    fast, ref = fem._vector_from_scalar_blocks(blocks, n), fem._vector_from_coo(blocks, n)
    for a, b in ((fast.indptr, ref.indptr), (fast.indices, ref.indices)):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert fast.data.tobytes() == ref.data.tobytes() and fast.shape == (3 * n, 3 * n)
    blocks[2][0] = sp.csr_matrix((np.ones(3), ([0, 1, 2], [3, 2, 1])), shape=(n, n))  # another pattern
    mixed = fem._vector_from_scalar_blocks(blocks, n)
    assert abs(mixed - fem._vector_from_coo(blocks, n)).max() == 0.0


def test_blocks_summed_on_one_plan_hold_the_bits_of_scipys_conversion():
    """The duplicates of shared COO coordinates added in scipy's order, replayed (``fem._coo_summer``): the CSR
    matrix of each value array is scipy's own, bit for bit, where the order of addition changes the sums
    (up to 12 duplicates per entry, values over 16 decades)."""
    rng = np.random.default_rng(11)
    n = 50
    r, c = rng.integers(0, n, 3000), rng.integers(0, n, 3000)
    arrays = [rng.standard_normal(3000) * 10.0 ** rng.integers(-8, 8, 3000) for _ in range(4)]
    to_csr = fem._coo_summer(r, c, n, arrays[0])
    for v in arrays:
        got, want = to_csr(v), sp.csr_matrix((v, (r, c)), shape=(n, n))
        for a, b in ((got.indptr, want.indptr), (got.indices, want.indices)):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert got.data.tobytes() == want.data.tobytes()
    summed_apart = sp.csr_matrix((arrays[1], (r, c)), shape=(n, n)).data
    assert not np.array_equal(np.sort(summed_apart), np.sort(np.bincount(r * n + c, arrays[1])[np.unique(r * n + c)]))


# ---------------------------------------------------------------- nested refinement (mesh check)
def test_halved_grid_is_nested_and_halves_the_chosen_cells():
    from jointid.config import load_config
    from jointid.config.typed import MeshOptions
    from jointid.geometry.mesh import mesh_from_config
    from jointid.geometry.rig import build_rig

    from conftest import REPO

    cfg = load_config(REPO / "config.yaml")
    rig = build_rig(cfg["rig"])
    base = mesh_from_config(rig, MeshOptions.from_section(cfg["mesh"])).mesh
    lines = [np.unique(np.round(base.p[i], 9)) for i in range(3)]
    for halve, axes in ((("thickness",), (1,)), (("plan",), (0, 2)), (("length",), (0,)), (("width",), (2,)),
                        (("joint_zone",), (0, 1, 2))):
        fine = mesh_from_config(rig, MeshOptions.from_section(cfg["mesh"]), halve=halve).mesh
        for i in range(3):
            fl = np.unique(np.round(fine.p[i], 9))
            assert np.isin(lines[i], fl).all(), (halve, i)  # every old grid line is kept
            if i in axes:
                assert len(fl) > len(lines[i])
            elif halve != ("joint_zone",):
                assert len(fl) == len(lines[i])
        # every old cell's edge along a halved axis is split into equal halves or kept
        for i in axes:
            fl = np.unique(np.round(fine.p[i], 9))
            for a, b in zip(lines[i][:-1], lines[i][1:]):
                inner = fl[(fl > a + 1e-9) & (fl < b - 1e-9)]
                assert len(inner) in (0, 1)
                if len(inner):
                    assert inner[0] == pytest.approx((a + b) / 2, abs=1e-9)
    with pytest.raises(ValueError, match="unknown cell classes"):
        mesh_from_config(rig, MeshOptions.from_section(cfg["mesh"]), halve=("everything",))


def test_nested_refinement_lowers_every_frequency():
    """Min-max principle: on a nested (richer) mesh no eigenfrequency can rise."""
    from jointid.correlate.pairing import pair_by_shapes
    from jointid.fe.model import base_coefficients, build_model

    from conftest import coarse_config_dict

    cfg = coarse_config_dict()
    out = []
    for halve in ((), ("thickness", "joint_zone")):
        model = build_model(ModelSpec.from_config(cfg), halve=halve)
        kc, mc = base_coefficients(ModelSpec.from_config(cfg), model)
        modes = solve_modes(model.K(kc), model.M(mc), 10, shift_Hz=-10.0, fixed=model.fixed)
        out.append((modes.freqs_Hz, model.probe @ modes.phi))
    (fc, sc), (ff, sf) = out
    assert len(fc) == len(ff) == 10
    # sorted eigenvalues of a nested space interlace from below: the k-th can only fall
    assert np.all(ff <= fc * (1 + 1e-8))
    assert np.any(ff < fc * (1 - 1e-4))  # and the refinement does change something
    index, macs = pair_by_shapes(sc, sf, threshold=0.8)
    # every mode but the top of the window (its partner may lie above it) is followed onto the fine mesh
    assert (index[:8] >= 0).all() and (macs[:8] > 0.9).all()
