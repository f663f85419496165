"""Effect library: term system (per-carriage split, bonded support), effect coefficients, config."""

import math

import numpy as np
import pytest

from jointid.diagnosis import effects as E
from jointid.diagnosis.terms import BONDED_N_PER_M3, StateInfo
from jointid.diagnosis import terms as T
from jointid.config import load_config
from jointid.response.emforce import carriage_loads_N
from jointid.errors import ConfigError
from jointid.fe.modal import solve_modes
from jointid.fe.model import base_coefficients, build_model
from jointid.config.typed import ModelSpec
from conftest import coarse_config_dict


@pytest.fixture(scope="module")
def setup():
    from jointid.threads import limit_threads

    limit_threads(1)
    cfg = coarse_config_dict()
    cfg = load_config(cfg)
    model = build_model(ModelSpec.from_config(cfg))
    return cfg, model, T.build_system(model, ModelSpec.from_config(cfg))


THETA = {"k_normal_N_per_m3": 8e11, "k_lateral_N_per_m3": 6e11, "k_feed_N_per_m3": 1e10}


def test_joint_layers_split_per_carriage_sum_to_the_layer(setup):
    cfg, model, system = setup
    assert system.n_carriages == 4
    for name in ("K_top_y", "K_flank_x", "K_top_z"):
        parts = [system.stiffness[f"{name}@{c}"] for c in range(4)]
        assert abs(sum(parts) - model.stiffness[name]).max() == 0.0
        # each part lives under its own carriage (X, Z of its DOFs near that carriage centre)
        for c, P in enumerate(parts):
            dofs = np.unique(P.tocoo().row) // 3
            xz = model.doflocs[[0, 2]][:, dofs].T
            d = np.linalg.norm(xz - system.carriage_xz_m[c], axis=1)
            assert d.max() < 0.5 * np.linalg.norm(system.carriage_xz_m[c] - system.carriage_xz_m[c - 1])


def test_bonded_foundation_reproduces_the_clamped_base(setup):
    cfg, model, system = setup
    assert system.support == "clamped" and len(system.fixed) == 0
    kc, mc = T.baseline_coefficients(system, ModelSpec.from_config(cfg), THETA)
    assert kc["K_foundation"] == BONDED_N_PER_M3
    kc0, mc0 = base_coefficients(ModelSpec.from_config(cfg), model, THETA)
    a = solve_modes(model.K(kc0), model.M(mc0), 8, fixed=model.fixed).freqs_Hz
    b = solve_modes(system.K(kc), system.M(mc), 8, fixed=system.fixed).freqs_Hz
    assert np.max(np.abs(b / a - 1)) < 1e-4


def test_carried_mass_is_table_carriages_and_motors(setup):
    cfg, model, system = setup
    rig = cfg["rig"]
    t, c, r = rig["table"], rig["carriages"], rig["rails"]
    rho_t = cfg["materials"][t["material"]]["density_kg_per_m3"]
    rho_c = cfg["materials"][c["material"]]["density_kg_per_m3"]
    table = t["length_m"] * t["width_m"] * t["thickness_m"] * rho_t
    h = c["height_m"] - c["ground_clearance_m"]
    inside = r["width_m"] * (r["height_m"] - c["ground_clearance_m"]) * c["length_m"]
    carriages = 4 * (c["length_m"] * c["width_m"] * h - inside) * rho_c
    motors = rig["motors"]["count"] * rig["motors"]["mass_each_kg"]
    assert system.carried_mass_kg == pytest.approx(table + carriages + motors, rel=1e-6)


def test_em_preload_scales_each_carriage_by_its_pressure_ratio(setup):
    cfg, model, system = setup
    kc, mc = T.baseline_coefficients(system, ModelSpec.from_config(cfg), THETA)
    eff = E.EFFECTS["em_preload"]
    off = StateInfo("off", 0.0)
    on = StateInfo("on", 1000.0)
    opts = dict(eff.options)
    k_off, _ = E.apply_effects(system, kc, mc, off, [(eff, {"beta": 0.4}, opts)])
    assert k_off == kc  # weight-only state is the calibrated baseline
    k_on, _ = E.apply_effects(system, kc, mc, on, [(eff, {"beta": 0.4}, opts)])
    w = system.carried_mass_kg * 9.81
    ratio = (1000.0 + w) / w  # centred load: every block carries a quarter
    for name in ("K_top_y@0", "K_flank_x@3"):
        assert k_on[name] == pytest.approx(kc[name] * ratio ** 0.4, rel=1e-12)
    assert k_on["K_top_z@2"] == kc["K_top_z@2"]  # feed direction: servo, not contact pressure
    assert k_on["K_railfix"] == kc["K_railfix"]
    # off-centre attraction: the per-carriage ratios follow the statics load share
    opts2 = {**opts, "force_x_m": 0.05, "preload_N": 200.0}
    r = E.pressure_ratio(system, on, opts2)
    x, z = system.carriage_xz_m.T
    lx = 1000.0 * 0.05 / (1000.0 + w)
    f_on = carriage_loads_N(1000.0, system.carried_mass_kg, x, z, load_x_m=lx) + 200.0
    f_off = carriage_loads_N(0.0, system.carried_mass_kg, x, z) + 200.0
    assert np.allclose(r, f_on / f_off)
    assert r[x > 0].min() > r[x < 0].max()  # the side the force leans to is pressed harder
    # only the requested directions follow the law
    k_y, _ = E.apply_effects(system, kc, mc, on, [(eff, {"beta": 0.4}, {**opts, "directions": ["y"]})])
    assert k_y["K_flank_x@0"] == kc["K_flank_x@0"] and k_y["K_top_y@0"] > kc["K_top_y@0"]
    k_z, _ = E.apply_effects(system, kc, mc, on, [(eff, {"beta": 0.4}, {**opts, "directions": ["x", "y", "z"]})])
    assert k_z["K_top_z@0"] == pytest.approx(kc["K_top_z@0"] * ratio ** 0.4)


def test_mass_compliance_and_feed_effects(setup):
    cfg, model, system = setup
    kc, mc = T.baseline_coefficients(system, ModelSpec.from_config(cfg), THETA)
    s = StateInfo("s", 0.0)
    _, m2 = E.apply_effects(system, kc, mc, s, [(E.EFFECTS["added_mass_table"], {"mass_kg": 3.0}, {})])
    assert m2["M_table_top"] == 3.0 and m2["M_motor"] == mc["M_motor"]
    _, m3 = E.apply_effects(system, kc, mc, s, [(E.EFFECTS["added_mass_edge"], {"mass_kg": 1.5}, {})])
    assert m3["M_table_edge"] == 1.5
    k2, _ = E.apply_effects(system, kc, mc, s, [(E.EFFECTS["rail_fixing"], {"k_railfix_N_per_m3": 2e12}, {})])
    assert k2["K_railfix"] == pytest.approx(1 / (1 / BONDED_N_PER_M3 + 1 / 2e12))
    k3, _ = E.apply_effects(system, kc, mc, s, [(E.EFFECTS["base_support"], {"k_foundation_N_per_m3": 3e11}, {})])
    assert k3["K_foundation"] == pytest.approx(1 / (1 / BONDED_N_PER_M3 + 1 / 3e11))
    k4, _ = E.apply_effects(system, kc, mc, s, [(E.EFFECTS["feed_stiffness"], {"k_feed_extra_N_per_m3": 5e9}, {})])
    for c in range(4):
        assert k4[f"K_top_z@{c}"] == pytest.approx(kc[f"K_top_z@{c}"] + 5e9)
        assert k4[f"K_flank_z@{c}"] == pytest.approx(kc.get(f"K_flank_z@{c}", 0.0) + 5e9)
        assert k4[f"K_top_y@{c}"] == kc[f"K_top_y@{c}"]
    # a null value changes nothing
    for eff in E.EFFECTS.values():
        k0, m0 = E.apply_effects(system, kc, mc, StateInfo("on", 1000.0), [(eff, eff.null_values(), eff.options)])
        assert k0 == kc and m0 == mc


def test_param_test_variable_round_trip():
    p = E.EFFECTS["rail_fixing"].params[0]
    assert p.to_t(math.inf) == 0.0 and p.from_t(0.0) == math.inf
    assert p.from_t(p.to_t(3e12)) == pytest.approx(3e12)
    assert p.t_bounds == (0.0, p.nominal / p.lower)
    q = E.EFFECTS["added_mass_table"].params[0]
    assert q.from_t(q.to_t(4.0)) == pytest.approx(4.0) and q.t_bounds == (0.0, 30.0 / q.nominal)


def test_enabled_effects_config():
    en = E.enabled_effects({"em_preload": {"beta": 0.2, "preload_N": 100.0},
                            "added_mass_edge": {"mass_kg": 1.0, "fit": False}})
    assert [e.effect.name for e in en] == ["em_preload", "added_mass_edge"]
    assert en[0].values == {"beta": 0.2} and en[0].options["preload_N"] == 100.0 and en[0].fit
    assert not en[1].fit
    assert E.enabled_effects({"rail_fixing": {}})[0].values["k_railfix_N_per_m3"] == 1e12  # nominal start
    with pytest.raises(ConfigError) as err:
        E.enabled_effects({"em_prelaod": {}, "added_mass_table": {"mass": 2, "mass_kg": 99.0},
                           "feed_stiffness": {"fit": "yes"}})
    lines = err.value.problems
    assert len(lines) == 4
    assert "did you mean 'em_preload'" in lines[0]
    assert any("effects.added_mass_table.mass: unknown key" in ln and "mass_kg" in ln for ln in lines)
    assert any("99 is outside the plausible range" in ln for ln in lines)
    assert any("effects.feed_stiffness.fit" in ln for ln in lines)
