"""Mesh in (``model: {kind: mesh}``): the non-matching joint layer against a patch test and the
analytic rigid block on springs, the rig's round trip through a mesh file, and clear errors on bad
meshes."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
import yaml
from skfem import Basis, ElementHex2, MeshHex

from jointid.config.load import load_config
from jointid.errors import ModelError
from jointid.fe.layer import spring_layer_terms
from jointid.fe.modal import solve_model
from jointid.fe.model import base_coefficients, build_model
from jointid.fe.meshexport import export_rig, write_mesh
from jointid.config.typed import ModelSpec

ROOT = Path(__file__).resolve().parents[1]
L, W, H_LOW, H_UP = 0.10, 0.08, 0.04, 0.05  # m: blocks' plan (X, Z) and heights
RHO, E = 7850.0, 2.0e13  # very stiff solids: the blocks move as rigid bodies on the layer
K_N, K_T = 6.0e8, 2.0e8  # N/m^3


def two_blocks(shift_y: float = 0.0):
    """Lower block (3 x 2 x 3 cells) and upper block (2 x 2 x 2, lines elsewhere): the interface
    y = 0 does not match.  Returns the corner mesh, cell groups and named surfaces."""
    lower = MeshHex.init_tensor(np.linspace(0, L, 4), np.linspace(-H_LOW, 0, 3), np.linspace(0, W, 4))
    upper = MeshHex.init_tensor(np.array([0, 0.37 * L, L]), np.linspace(0, H_UP, 3) + shift_y,
                                np.array([0, 0.61 * W, W]))
    n1, c1 = lower.p.shape[1], lower.t.shape[1]
    mesh = MeshHex(np.hstack([lower.p, upper.p]), np.hstack([lower.t, upper.t + n1]))
    bnd = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bnd]].mean(axis=1)
    up = mesh.f2t[0, bnd] >= c1
    surfaces = {"lower_top": bnd[np.isclose(mid[1], 0) & ~up],
                "upper_bottom": bnd[np.isclose(mid[1], shift_y) & up],
                "ground": bnd[np.isclose(mid[1], -H_LOW)],
                "upper_top": bnd[np.isclose(mid[1], H_UP + shift_y)]}
    groups = {"lower": np.arange(c1), "upper": np.arange(c1, mesh.t.shape[1])}
    return mesh, groups, surfaces


def block_config(tmp_path, mesh_file: str, **model):
    pts = tmp_path / "points.csv"
    pts.write_text(f"point,x_m,y_m,z_m\nP1,{L / 2},{H_UP},{W / 2}\nP2,{L},{H_UP / 2},{W / 3}\n")
    section = {"kind": "mesh", "path": mesh_file, "bodies": {"lower": "stiff", "upper": "stiff"},
               "joints": [{"name": "slide", "surfaces": ["upper_bottom", "lower_top"], "feed_axis": [0, 0, 1],
                           "law": {"normal": "k_normal_N_per_m3", "tangential": "k_feed_N_per_m3"}}],
               "supports": [{"surface": "ground", "kind": "clamped"}], "points": str(pts)}
    section.update(model)
    return load_config(ROOT / "config.yaml", overrides={
        "model": section,
        "materials": {"stiff": {"youngs_modulus_Pa": E, "poisson_ratio": 0.3, "density_kg_per_m3": RHO}},
        "mesh": {"extrapolate_edges": False},
        "joints": {"parameters": {"k_normal_N_per_m3": {"direction": "y", "lower": 1e8, "upper": 1e9},
                                  "k_feed_N_per_m3": {"direction": "z", "lower": 1e8, "upper": 1e9},
                                  "k_lateral_N_per_m3": None},  # null removes config.yaml's third parameter
                   "fixed": {}}})


def rigid_block_frequencies() -> np.ndarray:
    """The six frequencies (Hz) of the upper block as a rigid body on the layer (k_n normal, k_t in
    both tangential directions), from the 6 x 6 stiffness integrated exactly over the contact."""
    m = RHO * L * W * H_UP
    c = np.array([L / 2, H_UP / 2, W / 2])
    inertia = m / 12 * np.array([H_UP ** 2 + W ** 2, L ** 2 + W ** 2, L ** 2 + H_UP ** 2])
    Mr = np.diag([m, m, m, *inertia])
    g, gw = np.polynomial.legendre.leggauss(3)
    K = np.zeros((6, 6))
    D = np.diag([K_T, K_N, K_T])
    for xi, wx in zip(g, gw):
        for zi, wz in zip(g, gw):
            r = np.array([L / 2 * (xi + 1), 0.0, W / 2 * (zi + 1)]) - c
            skew = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
            T = np.hstack([np.eye(3), -skew])  # u = U + theta x r
            K += wx * wz * (L / 2) * (W / 2) * T.T @ D @ T
    lam = np.linalg.eigvalsh(np.linalg.solve(np.linalg.cholesky(Mr), np.linalg.solve(np.linalg.cholesky(Mr), K).T))
    return np.sqrt(np.sort(lam)) / (2 * np.pi)


def test_layer_patch_test_gives_the_exact_total_force_on_non_matching_meshes():
    """A uniform relative displacement d of the upper block: the layer's force on it is k A (e.d) e in
    each component e, exactly (partition of unity on both sides)."""
    mesh, groups, surfaces = two_blocks()
    basis = Basis(mesh, ElementHex2(), intorder=4)
    terms, info = spring_layer_terms(basis, surfaces["upper_bottom"], surfaces["lower_top"],
                                     ["normal", "feed", "lateral", "tangential", "all", "x"], intorder=4,
                                     feed_axis=[0, 0, 1])
    assert info["area_m2"] == pytest.approx(L * W, rel=1e-12)
    up = np.zeros(basis.N, bool)
    up[np.unique(basis.element_dofs[:, groups["upper"]])] = True
    d = np.array([0.3, -0.7, 1.1])
    u = np.zeros(3 * basis.N)
    for c in range(3):
        u[3 * np.flatnonzero(up) + c] = d[c]
    # outward normal of the upper block's bottom face is -y; feed z; lateral n x feed = +-x
    expected = {"normal": [0, d[1], 0], "feed": [0, 0, d[2]], "lateral": [d[0], 0, 0],
                "tangential": [d[0], 0, d[2]], "all": d, "x": [d[0], 0, 0]}
    for comp, K in terms.items():
        F = K @ u
        on_upper = [F[3 * np.flatnonzero(up) + c].sum() for c in range(3)]
        on_lower = [F[3 * np.flatnonzero(~up) + c].sum() for c in range(3)]
        np.testing.assert_allclose(on_upper, L * W * np.asarray(expected[comp], float), rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(on_lower, -np.asarray(on_upper), rtol=1e-10, atol=1e-14)
        assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


@pytest.mark.parametrize("ext", [".msh", ".vtu", ".inp"])
def test_rigid_block_on_a_non_matching_layer_has_the_analytic_frequencies(tmp_path, ext):
    """Through each file format (gmsh physical groups, VTK cell data, Abaqus element sets)."""
    mesh, groups, surfaces = two_blocks()
    write_mesh(tmp_path / f"blocks{ext}", mesh, groups, surfaces)
    cfg = block_config(tmp_path, str(tmp_path / f"blocks{ext}"))
    model = build_model(ModelSpec.from_config(cfg))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, {"k_normal_N_per_m3": K_N, "k_feed_N_per_m3": K_T})
    assert kc == {"K_slide_normal": K_N, "K_slide_tangential": K_T}
    modes = solve_model(model, kc, mc, 8)
    exact = rigid_block_frequencies()
    np.testing.assert_allclose(modes.freqs_Hz[:6], exact, rtol=5e-3)
    assert modes.freqs_Hz[6] > 10 * exact[-1]  # the next mode is elastic, far above
    assert model.probe.shape == (6, model.n_dofs)


@pytest.mark.parametrize("ext", [".msh", ".vtu"])
def test_rig_exported_as_a_mesh_file_and_read_back_has_the_same_frequencies(tmp_path, ext):
    coarse = yaml.safe_load((ROOT / "tests" / "coarse_config.yaml").read_text())
    overrides = {"mesh": coarse["mesh"]}
    cfg = load_config(ROOT / "config.yaml", overrides=overrides)
    rig = build_model(ModelSpec.from_config(cfg))
    section = export_rig(ModelSpec.from_config(cfg), tmp_path / f"rig{ext}", tmp_path / "points.csv")
    cfg_mesh = load_config(ROOT / "config.yaml", overrides={"mesh": {"extrapolate_edges": False}, "model": section})
    mesh = build_model(ModelSpec.from_config(cfg_mesh))
    assert mesh.n_dofs == rig.n_dofs
    theta = {"k_normal_N_per_m3": 1.3e12, "k_lateral_N_per_m3": 5.1e11, "k_feed_N_per_m3": 2.2e10}
    a = solve_model(rig, *base_coefficients(ModelSpec.from_config(cfg), rig, theta), 20)
    b = solve_model(mesh, *base_coefficients(ModelSpec.from_config(cfg_mesh), mesh, theta), 20)
    np.testing.assert_allclose(b.freqs_Hz, a.freqs_Hz, rtol=1e-6)
    # the measuring points read back from the CSV and projected onto the surface see the same shapes
    pa, pb = rig.probe @ a.phi, mesh.probe @ b.phi
    mac = (np.einsum("ij,ij->j", pa, pb) ** 2) / (np.einsum("ij,ij->j", pa, pa) * np.einsum("ij,ij->j", pb, pb))
    assert mac.min() > 1 - 1e-8


def _problems(excinfo) -> str:
    return str(excinfo.value)


def test_bad_meshes_get_errors_naming_file_group_and_fix(tmp_path):
    mesh, groups, surfaces = two_blocks()
    f = tmp_path / "blocks.msh"
    write_mesh(f, mesh, groups, surfaces)
    # an unknown body group and an unknown surface: both named, with the groups the file has
    cfg = block_config(tmp_path, str(f), bodies={"lower": "stiff", "uper": "stiff"},
                       supports=[{"surface": "floor", "kind": "clamped"}])
    with pytest.raises(ModelError) as exc:
        build_model(ModelSpec.from_config(cfg))
    msg = _problems(exc)
    assert f"{f}: model.bodies.uper: no solid group 'uper' in the mesh" in msg
    assert "model.supports[0]: no surface group 'floor'" in msg and "'upper_bottom'" in msg
    # cells in no body
    with pytest.raises(ModelError, match="solid cells are in no group of model.bodies"):
        build_model(ModelSpec.from_config(block_config(tmp_path, str(f), bodies={"lower": "stiff"})))
    # surfaces further apart than the tolerance
    mesh2, groups2, surfaces2 = two_blocks(shift_y=0.01)
    f2 = tmp_path / "gap.msh"
    write_mesh(f2, mesh2, groups2, surfaces2)
    with pytest.raises(ModelError, match=r"joint slide \(upper_bottom - lower_top\): the surfaces are up to 0.01 m "
                                         r"apart \(tolerance 0.001 m\)"):
        build_model(ModelSpec.from_config(block_config(tmp_path, str(f2))))
    # a measuring point off the surface
    cfg = block_config(tmp_path, str(f))
    Path(cfg["model"]["points"]).write_text("point,x_m,y_m,z_m\nFAR,0.05,0.2,0.04\n")
    with pytest.raises(ModelError, match=r"point FAR is 0.15 m from the nearest surface"):
        build_model(ModelSpec.from_config(cfg))


def test_linear_cells_need_allow_linear_and_a_surface_off_the_bodies_is_an_error(tmp_path):
    mesh, groups, surfaces = two_blocks()
    from skfem.io.meshio import HEX_MAPPING

    hexes = mesh.t[HEX_MAPPING[:8]].T
    quads = mesh.facets[:, surfaces["lower_top"]].T
    stray = np.array([[0, 1, 2, 3]]) + mesh.p.shape[1]  # a face on nodes of no cell
    points = np.vstack([mesh.p.T, [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]]])
    tags = {"lower": 1, "upper": 2, "lower_top": 3, "stray": 4}
    hex_tag = np.where(np.arange(len(hexes)) < len(groups["lower"]), 1, 2)
    m = meshio.Mesh(points, [("hexahedron", hexes), ("quad", np.vstack([quads, stray]))],
                    cell_data={"gmsh:physical": [hex_tag, np.r_[np.full(len(quads), 3), 4]],
                               "gmsh:geometrical": [hex_tag, np.r_[np.full(len(quads), 3), 4]]},
                    field_data={k: np.array([v, 3 if v < 3 else 2]) for k, v in tags.items()})
    f = tmp_path / "linear.msh"
    meshio.write(f, m, file_format="gmsh22", binary=False)
    cfg = block_config(tmp_path, str(f))
    with pytest.raises(ModelError, match=r"linear hexahedron cells lock in bending .* set model.allow_linear: true"):
        build_model(ModelSpec.from_config(cfg))
    cfg = block_config(tmp_path, str(f), allow_linear=True)
    with pytest.raises(ModelError, match=r"surface 'stray': 1 of 1 faces use nodes of no solid cell"):
        with pytest.warns(Warning):
            build_model(ModelSpec.from_config(cfg))


def test_measuring_points_from_a_uff_geometry_give_the_probe_of_the_csv(tmp_path):
    """model.points may be a Universal File's node geometry (dataset 15): same interpolation as the
    CSV of the same points, named by node number."""
    import pyuff

    mesh, groups, surfaces = two_blocks()
    write_mesh(tmp_path / "blocks.msh", mesh, groups, surfaces)
    cfg = block_config(tmp_path, str(tmp_path / "blocks.msh"))
    ref = build_model(ModelSpec.from_config(cfg))
    xyz = np.array([[L / 2, H_UP, W / 2], [L, H_UP / 2, W / 3]])
    uff = pyuff.UFF(str(tmp_path / "geometry.unv"))
    uff.write_sets(pyuff.prepare_15(node_nums=[101, 102], def_cs=[0, 0], disp_cs=[0, 0], color=[1, 1],
                                    x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2]), mode="overwrite")
    cfg["model"]["points"] = str(tmp_path / "geometry.unv")
    model = build_model(ModelSpec.from_config(cfg))
    assert model.meta["points"]["point"] == ["101", "102"]
    read = np.column_stack([model.meta["points"][k] for k in ("x_m", "y_m", "z_m")])
    np.testing.assert_allclose(read, xyz, atol=1e-6)  # UFF 15 stores coordinates to about 6 digits
    assert abs(model.probe - ref.probe).max() < 1e-4


def test_export_mesh_command_writes_a_mesh_and_an_overlay_that_reads_it_back(tmp_path, capsys):
    from jointid.cli import main

    coarse = ROOT / "tests" / "coarse_config.yaml"
    assert main(["export-mesh", "--out", str(tmp_path / "own"), "--format", "vtu",
                 "--config", str(ROOT / "config.yaml"), str(coarse)]) == 0
    assert "export-mesh: wrote" in capsys.readouterr().out
    overlay = yaml.safe_load((tmp_path / "own" / "model.yaml").read_text())
    assert overlay["model"]["path"].endswith("rig.vtu") and overlay["mesh"] == {"extrapolate_edges": False}
    rig = build_model(ModelSpec.from_config(load_config(ROOT / "config.yaml", overrides={"mesh": yaml.safe_load(coarse.read_text())["mesh"]})))
    mesh = build_model(ModelSpec.from_config(load_config(ROOT / "config.yaml", overrides=overlay)))
    assert mesh.n_dofs == rig.n_dofs and mesh.meta["carriage_centres_m"] and len(mesh.meta["carriage_centres_m"]) == 4
