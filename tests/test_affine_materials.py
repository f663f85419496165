"""The model affine in the solids' materials and the added masses, not only in the joints.

``build_model`` keeps the solids per part (``K_solid_<part>``, ``M_solid_<part>``, fe/model.py): at the
reference materials the model is the one it was before the split (frequencies to 1e-9), a changed
Young's modulus, density, Poisson's ratio (the Lamé split, fe/lame.py) or motor mass given as
coefficients of one model equals the model built with it, and the part terms are the parts' own
elasticity and mass.
"""

import dataclasses

import numpy as np
import pytest

from jointid.config import load_config
from jointid.errors import ModelError
from jointid.fe import fem
from jointid.fe.lame import add_lame_terms
from jointid.fe.modal import solve_modes
from jointid.fe.model import base_coefficients, build_model, load_model, save_model, solid_coefficients
from jointid.yamlio import deep_merge
from jointid.config.typed import ModelSpec
from conftest import coarse_config_dict

N_MODES = 14
# The coarse config's model at its default coefficients (joints at the geometric mean of their bounds),
# first 14 frequencies in Hz as the model built them before the split into parts (commit ef6f0de).
BEFORE_SPLIT_HZ = [433.6972304, 1363.74154574, 1442.25602292, 1467.78362314, 2054.68868853,
                   2159.02457169, 2502.79543831, 3359.98982863, 3777.04114255, 4021.30385345,
                   4039.12294592, 4120.80336554, 4502.58851582, 4777.56484082]


def _freqs(model, kc, mc):
    return solve_modes(model.K(kc), model.M(mc), N_MODES, fixed=model.fixed, shift_Hz=-10.0).freqs_Hz


@pytest.fixture(scope="module")
def run():
    cfg = load_config(coarse_config_dict())
    return cfg, build_model(ModelSpec.from_config(cfg))


def test_default_frequencies_are_those_before_the_split(run):
    cfg, model = run
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model)
    assert not any("_solid_" in k for k in (*kc, *mc))  # reference materials: no solid coefficient
    f = _freqs(model, kc, mc)
    # 1.5e-10 s: the frequencies printed to 12 significant digits
    np.testing.assert_allclose(f, BEFORE_SPLIT_HZ, rtol=1e-9)


def test_part_terms_are_the_parts_elasticity_and_mass(run):
    cfg, model = run
    info = model.meta["solids"]
    assert info["complement"] == "base"
    assert set(model.solids) == {f"{g}_solid_{p}" for g in "KM" for p in ("rail", "carriage", "table")}
    r = cfg["rig"]
    ey = np.zeros(model.n_dofs)
    ey[1::3] = 1.0
    # partition of unity: e_y^T M_part e_y is the part's mass
    table = 2700.0 * r["table"]["length_m"] * r["table"]["width_m"] * r["table"]["thickness_m"]
    base = 7850.0 * r["base"]["length_m"] * r["base"]["width_m"] * r["base"]["height_m"]
    rails = 2 * 7850.0 * r["rails"]["width_m"] * r["rails"]["height_m"] * r["rails"]["length_m"]
    assert ey @ (model.solid_term("M_solid_table") @ ey) == pytest.approx(table, rel=1e-9)
    assert ey @ (model.solid_term("M_solid_base") @ ey) == pytest.approx(base, rel=1e-9)
    assert ey @ (model.solid_term("M_solid_rail") @ ey) == pytest.approx(rails, rel=1e-9)
    # every part is stress-free under a rigid translation, and the parts add up to the solids
    ones = np.ones(model.n_dofs)
    K0 = model.stiffness["K0"]
    total = sum(model.solid_term(f"K_solid_{p}") for p in ("base", "rail", "carriage", "table"))
    assert abs(total - K0).max() <= 1e-12 * abs(K0).max()
    for p in ("base", "table"):
        Kp = model.solid_term(f"K_solid_{p}")
        assert np.abs(Kp @ ones).max() <= 1e-8 * abs(Kp).max()
        assert Kp.nnz < K0.nnz
    with pytest.raises(KeyError, match="no term named 'K_solid_motor'"):
        model.solid_term("K_solid_motor")


@pytest.mark.parametrize("change", [
    {"materials": {"aluminium": {"youngs_modulus_Pa": 7.2e10, "density_kg_per_m3": 1350.0}}},  # table only
    {"materials": {"steel": {"youngs_modulus_Pa": 1.9e11}}, "rig": {"motors": {"mass_each_kg": 1.0}}},
])
def test_coefficients_equal_the_model_built_with_the_change(run, change):
    cfg, model = run
    cfg2 = load_config(deep_merge(coarse_config_dict(), change))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg2), model)
    assert any("_solid_" in k for k in (*kc, *mc))
    own = build_model(ModelSpec.from_config(cfg2))
    f_affine = _freqs(model, kc, mc)
    f_own = _freqs(own, *base_coefficients(ModelSpec.from_config(cfg2), own))
    np.testing.assert_allclose(f_affine, f_own, rtol=1e-9)
    assert np.abs(f_affine / np.array(BEFORE_SPLIT_HZ) - 1).max() > 1e-3  # the change is seen


STEEL_TABLE = {"rig": {"table": {"material": "steel"}}}  # E, density and Poisson's ratio 0.33 -> 0.30


def test_a_changed_poisson_ratio_needs_the_volumetric_term(run):
    cfg, model = run
    spec = ModelSpec.from_config(load_config(deep_merge(coarse_config_dict(), STEEL_TABLE)))
    bare = dataclasses.replace(model, solids=dict(model.solids))
    with pytest.raises(ModelError, match="Poisson's ratio 0.3, the model was built with 0.33"):
        solid_coefficients(spec, bare)
    assert add_lame_terms(spec, bare) == ["K_lambda_table"]
    kc, mc = solid_coefficients(spec, bare)
    lam, mu = fem.lame(2.06e11, 0.30)
    lam0, mu0 = fem.lame(7.0e10, 0.33)
    assert kc == {"K_solid_table": pytest.approx(mu / mu0 - 1), "K_lambda_table": pytest.approx(lam / lam0 - mu / mu0)}
    assert mc == {"M_solid_table": pytest.approx(7850.0 / 2700.0 - 1)}


def test_the_volumetric_term_is_the_parts_lambda_form(run):
    # u = x e_x: a uniform strain eps_xx = 1, div u = 1, so u^T K_lambda u = lambda_0 V and
    # u^T K_solid u = (lambda_0 + 2 mu_0) V over the table's volume V; a rigid translation strains nothing
    cfg, model = run
    spec = ModelSpec.from_config(load_config(deep_merge(coarse_config_dict(), STEEL_TABLE)))
    m = dataclasses.replace(model, solids=dict(model.solids))
    add_lame_terms(spec, m)
    r = cfg["rig"]["table"]
    volume = r["length_m"] * r["width_m"] * r["thickness_m"]
    lam0, mu0 = fem.lame(7.0e10, 0.33)
    u = np.zeros(m.n_dofs)
    u[0::3] = m.doflocs[0]
    KL, KS = m.solid_term("K_lambda_table"), m.solid_term("K_solid_table")
    assert u @ (KL @ u) == pytest.approx(lam0 * volume, rel=1e-9)
    assert u @ (KS @ u) == pytest.approx((lam0 + 2 * mu0) * volume, rel=1e-9)
    ones = np.ones(m.n_dofs)
    assert np.abs(KL @ ones).max() <= 1e-8 * abs(KL).max()
    assert abs(KL - KL.T).max() <= 1e-12 * abs(KL).max()


def test_a_poisson_change_as_coefficients_equals_the_model_built_with_it(run):
    cfg, model = run
    model = dataclasses.replace(model, solids=dict(model.solids))
    spec2 = ModelSpec.from_config(load_config(deep_merge(coarse_config_dict(), STEEL_TABLE)))
    add_lame_terms(spec2, model)
    own = build_model(spec2)
    f_affine = _freqs(model, *base_coefficients(spec2, model))
    f_own = _freqs(own, *base_coefficients(spec2, own))
    print(f"Lame split against the model built with it: {np.abs(f_affine / f_own - 1).max():.1e}")
    np.testing.assert_allclose(f_affine, f_own, rtol=1e-9)
    assert np.abs(f_affine / np.array(BEFORE_SPLIT_HZ) - 1).max() > 1e-3  # the change is seen


def test_the_volumetric_term_needs_the_models_own_mesh(run):
    _, model = run
    coarser = deep_merge(coarse_config_dict(), {**STEEL_TABLE, "mesh": {"max_cell_size_m": 0.1}})
    with pytest.raises(ModelError, match="the mesh of this configuration is not the model's"):
        add_lame_terms(ModelSpec.from_config(load_config(coarser)), dataclasses.replace(model, solids=dict(model.solids)))


def test_the_file_keeps_the_parts_but_the_largest(run, tmp_path):
    cfg, model = run
    path = tmp_path / "m.npz"
    save_model(model, path)
    back = load_model(path)
    assert set(back.solids) == set(model.solids)
    cfg2 = load_config(deep_merge(coarse_config_dict(), {"materials": {"steel": {"density_kg_per_m3": 7000.0}}}))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg2), back)
    assert set(mc) >= {"M_solid_base", "M_solid_rail", "M_solid_carriage"}
    assert abs(back.M(mc) - model.M(mc)).max() == 0.0
    assert abs(back.K(kc) - model.K(kc)).max() == 0.0


def test_coefficients_hold_on_a_mesh_with_hanging_nodes():
    # mesh.edge_refine_levels: the solid terms (and the volumetric term of a Poisson change, assembled
    # later) are projected onto the free nodes like every other term
    raw = deep_merge(coarse_config_dict(), {"mesh": {"edge_refine_levels": 1}})
    change = {"materials": {"aluminium": {"youngs_modulus_Pa": 6.0e10, "density_kg_per_m3": 1350.0,
                                          "poisson_ratio": 0.25}},
              "rig": {"motors": {"mass_each_kg": 1.0}}}
    model = build_model(ModelSpec.from_config(load_config(raw)))
    cfg2 = load_config(deep_merge(raw, change))
    assert add_lame_terms(ModelSpec.from_config(cfg2), model) == ["K_lambda_table"]
    own = build_model(ModelSpec.from_config(cfg2))
    assert model.n_dofs == own.n_dofs and "K_solid_table" in model.solids
    np.testing.assert_allclose(_freqs(model, *base_coefficients(ModelSpec.from_config(cfg2), model)),
                               _freqs(own, *base_coefficients(ModelSpec.from_config(cfg2), own)), rtol=1e-9)
