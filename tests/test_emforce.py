"""Linear-motor normal force, the dial-indicator method and the load share on the carriage blocks."""

import warnings

import numpy as np
import pytest

from jointid.response import emforce as em
from jointid.errors import DataError, NumericalWarning


# ---------------------------------------------------------------- Fc = Kd Lm Im^2 - Ku Io^2
def test_vertical_force_formula():
    # Kd 40 N/(H A^2), Lm 5 mH, Im 80 A -> 1280 N; Ku 0.5 N/A^2, Io 10 A -> 50 N
    assert em.vertical_force_N(40.0, 5e-3, 80.0, 0.5, 10.0) == pytest.approx(1230.0, rel=1e-14)
    assert em.vertical_force_N(40.0, 5e-3, 80.0, 0.0, 0.0) == pytest.approx(1280.0, rel=1e-14)
    sweep = em.vertical_force_N(40.0, 5e-3, np.array([0.0, 40.0, 80.0]), 0.0, 0.0)
    np.testing.assert_allclose(sweep, [0.0, 320.0, 1280.0])      # quadratic in the current


@pytest.mark.parametrize("bad, name", [
    (dict(exciting_current_A=-3.0), "exciting_current_A"),
    (dict(inductance_H=None), "inductance_H"),
    (dict(attraction_constant=float("nan")), "attraction_constant"),
    (dict(repulsion_constant=-1.0), "repulsion_constant"),
    (dict(eddy_current_A="ten"), "eddy_current_A"),
])
def test_vertical_force_rejects_bad_inputs_naming_the_argument(bad, name):
    args = dict(attraction_constant=40.0, inductance_H=5e-3, exciting_current_A=80.0,
                repulsion_constant=0.5, eddy_current_A=10.0) | bad
    with pytest.raises(DataError) as err:
        em.vertical_force_N(**args)
    assert str(err.value).startswith(name)
    assert ">= 0" in str(err.value) or "give" in str(err.value)


def test_vertical_force_reports_all_problems_and_warns_on_net_repulsion():
    with pytest.raises(DataError) as err:
        em.vertical_force_N(-1.0, None, 80.0, 0.5, -2.0)
    assert len(err.value.problems) == 3
    with pytest.warns(NumericalWarning, match="negative"):
        em.vertical_force_N(1.0, 1e-3, 10.0, 1.0, 10.0)


# ---------------------------------------------------------------- dial-indicator method
def test_indicator_inversion_exact_for_noise_free_calibration():
    forces = np.array([0.0, 400.0, 800.0, 1200.0, 1600.0, 2000.0])
    a, c = 1.5, 0.0125                                     # um, um/N
    fc_true = 1234.5
    out = em.force_from_indicator(a + c * fc_true, forces, a + c * forces)
    assert out.force_N == pytest.approx(fc_true, rel=1e-12)
    assert out.std_N == pytest.approx(0.0, abs=1e-9)
    assert out.slope_um_per_N == pytest.approx(c, rel=1e-12)
    assert out.intercept_um == pytest.approx(a, rel=1e-12)
    assert not out.extrapolated


def test_indicator_uncertainty_matches_monte_carlo():
    rng = np.random.default_rng(1)
    forces = np.repeat([0.0, 500.0, 1000.0, 1500.0, 2000.0], 2)
    a, c, sigma, fc_true = 0.8, 0.01, 0.3, 1700.0
    y0 = a + c * fc_true
    est, u2 = [], []
    for _ in range(3000):
        out = em.force_from_indicator(y0, forces, a + c * forces + rng.normal(0, sigma, forces.size))
        est.append(out.force_N)
        u2.append(out.std_N**2)
    assert np.std(est) == pytest.approx(np.sqrt(np.mean(u2)), rel=0.06)
    assert abs(np.mean(est) - fc_true) < 3 * np.std(est) / np.sqrt(len(est)) + 1e-6 * fc_true


def test_indicator_extrapolation_warns_and_bad_calibration_raises():
    forces = np.array([0.0, 200.0, 400.0])
    readings = 0.01 * forces
    with pytest.warns(NumericalWarning, match="extrapolated"):
        out = em.force_from_indicator(10.0, forces, readings)
    assert out.extrapolated and out.force_N == pytest.approx(1000.0)
    with pytest.raises(DataError, match="not strictly monotonic"):
        em.force_from_indicator(2.0, forces, [0.0, 3.0, 2.5])
    with pytest.raises(DataError, match="at least 2"):
        em.force_from_indicator(2.0, [100.0, 100.0], [1.0, 1.1])
    with pytest.raises(DataError, match="one reading per applied force"):
        em.force_from_indicator(2.0, forces, [0.0, 3.0])
    with pytest.raises(DataError) as err:
        em.force_from_indicator(None, forces, readings)
    assert str(err.value).startswith("powered_reading_um")


# ---------------------------------------------------------------- load share on four blocks
A_M, B_M = 0.12, 0.10
X = np.array([A_M, -A_M, A_M, -A_M])
Z = np.array([B_M, B_M, -B_M, -B_M])


def test_carriage_loads_formula_sum_and_moments():
    fc, mass, g, lx, lz = 1200.0, 35.0, 9.81, 0.03, -0.02
    loads = em.carriage_loads_N(fc, mass, X, Z, lx, lz, g=g)
    w = fc + mass * g
    expected = w / 4 * (1 + np.sign(X) * lx / A_M + np.sign(Z) * lz / B_M)
    np.testing.assert_allclose(loads, expected, rtol=1e-12)
    assert loads.sum() == pytest.approx(w, rel=1e-12)
    assert loads @ X == pytest.approx(w * lx, rel=1e-12)
    assert loads @ Z == pytest.approx(w * lz, rel=1e-12)
    centred = em.carriage_loads_N(fc, mass, X, Z)
    np.testing.assert_allclose(centred, w / 4, rtol=1e-12)


def test_carriage_loads_general_layout_balances():
    x = np.array([0.2, -0.1, 0.15, -0.12, 0.0])
    z = np.array([0.1, 0.12, -0.08, -0.1, 0.3])
    loads = em.carriage_loads_N(500.0, 10.0, x, z, 0.01, 0.02)
    w = 500.0 + 10.0 * 9.81
    assert loads.sum() == pytest.approx(w)
    assert loads @ x == pytest.approx(w * 0.01)
    assert loads @ z == pytest.approx(w * 0.02)


def test_carriage_lift_off_warns_and_bad_layout_raises():
    with pytest.warns(NumericalWarning, match="negative load"):
        loads = em.carriage_loads_N(1000.0, 0.0, X, Z, 0.2, 0.0)
    assert loads.min() < 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        em.carriage_loads_N(1000.0, 0.0, X, Z, 0.05, 0.05)
    with pytest.raises(DataError, match="one line"):
        em.carriage_loads_N(1000.0, 0.0, [0.0, 0.1, 0.2, 0.3], [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(DataError) as err:
        em.carriage_loads_N(1000.0, -5.0, X, Z[:3])
    text = str(err.value)
    assert "table_mass_kg" in text and "carriage_z_m has 3" in text


def test_contact_pressure():
    assert em.contact_pressure_Pa(450.0, 1.5e-3, preload_N=300.0) == pytest.approx(5.0e5)
    np.testing.assert_allclose(em.contact_pressure_Pa(np.array([0.0, 150.0]), 1.5e-3), [0.0, 1e5])
    with pytest.raises(DataError, match="area_m2"):
        em.contact_pressure_Pa(450.0, 0.0)
    with pytest.warns(NumericalWarning, match="opens"):
        em.contact_pressure_Pa(-100.0, 1e-3)
