"""Table 1 made honest (jointid.response.ranges): the paired minimum, the three damping laws on a 2-DOF
system against direct solves, how K_min scales between joint states, and the ranges table."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.linalg as la

from jointid.response import ranges as rg
from jointid.stages.harmonic import status_text

M = np.diag([10.0, 20.0])  # table (driven) on the joint, carriage on a base spring (kg)
K_BASE = 4.0e8  # N/m


def two_dof(k_joint):
    """``K, K_joint, freqs_Hz, phi`` (mass-normalised) and the joint shares of the 2-DOF system."""
    Kj = k_joint * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K = Kj + np.diag([0.0, K_BASE])
    w2, phi = la.eigh(K, M)
    w = np.sqrt(w2)
    share = np.einsum("ir,ij,jr->r", phi, Kj, phi) / w2
    return K, Kj, w / (2 * np.pi), phi, share


P = np.array([1.0, 0.0])  # drive and response at the table
BAND = (50.0, 3000.0)


def direct_min(K, Kj, f_grid, *, eta=0.0, gamma=0.0):
    """min |F/X| of ``p^T (K (+ i gamma K_j) - w^2 M + i w eta K_j)^-1 p`` on a grid."""
    kd = []
    for f in f_grid:
        w = 2 * np.pi * f
        A = K + 1j * gamma * Kj - w**2 * M + 1j * w * eta * Kj
        kd.append(1.0 / abs(P @ np.linalg.solve(A, P)))
    return min(kd)


def fine_grid(freqs_Hz, zeta):
    return np.unique(np.concatenate([np.linspace(*BAND, 4001)] + [f * (1 + np.linspace(-4, 4, 801) * z)
                                                                 for f, z in zip(freqs_Hz, zeta)]))


def test_joint_dashpot_ratio_is_the_modal_projection_of_c_eta_k_joint():
    _, Kj, fr, phi, share = two_dof(2.0e8)
    eta = 3.0e-6
    zeta, g = rg.law_damping("joint_dashpot", fr, share, eta)
    w = 2 * np.pi * fr
    np.testing.assert_allclose(zeta, np.einsum("ir,ij,jr->r", phi, eta * Kj, phi) / (2 * w), rtol=1e-12)
    assert not g.any()
    zeta_h, g_h = rg.law_damping("joint_hysteretic", fr, share, 0.1)
    np.testing.assert_allclose(g_h, 0.1 * share, rtol=1e-12) and not zeta_h.any()
    assert 0.2 < share.min() < share.max() < 0.9  # the joint carries part of each mode's strain energy


@pytest.mark.parametrize("law", rg.LAWS)
def test_calibration_gives_the_calibration_mode_the_target_ratio(law):
    _, _, fr, _, share = two_dof(2.0e8)
    param = rg.calibrate(law, 0.03, fr[0], share[0])
    zeta, g = rg.law_damping(law, fr, share, param)
    assert zeta[0] + g[0] / 2 == pytest.approx(0.03, rel=1e-12)


@pytest.mark.parametrize("law", ["joint_dashpot", "joint_hysteretic"])
def test_modal_k_min_of_the_joint_laws_matches_a_direct_solve(law):
    K, Kj, fr, phi, share = two_dof(2.0e8)
    param = rg.calibrate(law, 0.02, fr[0], share[0])
    zeta, g = rg.law_damping(law, fr, share, param)
    m = rg.band_minimum(BAND, fr, zeta, g, P @ phi, n_freq=4001)
    kw = {"eta": param} if law == "joint_dashpot" else {"gamma": param}
    ref = direct_min(K, Kj, fine_grid(fr, zeta + g / 2), **kw)
    assert m["k_min_N_per_m"] == pytest.approx(ref, rel=0.02)


def test_k_min_with_joint_dashpots_scales_as_modal_stiffness_times_omega_times_share():
    """Between two joint states the governing mode's joint share changes, so K_min ~ eta w_r e_r k_r does
    not scale as (f_on/f_off)^3 (which assumes e_r = 1 and an unchanged modal mass)."""
    out = {}
    eta = None
    for state, kj in (("off", 2.0e8), ("on", 3.2e8)):
        K, Kj, fr, phi, share = two_dof(kj)
        eta = eta or rg.calibrate("joint_dashpot", 0.02, fr[0], share[0])  # calibrated once, power-off
        zeta, g = rg.law_damping("joint_dashpot", fr, share, eta)
        pphi = P @ phi
        m = rg.band_minimum(BAND, fr, zeta, g, pphi, n_freq=4001)
        r = m["mode"]
        k_r = (2 * np.pi * fr[r]) ** 2 / pphi[r] ** 2
        out[state] = dict(k=direct_min(K, Kj, fine_grid(fr, zeta), eta=eta), mode=r, k_r=k_r, w=2 * np.pi * fr[r],
                          e=share[r], f=fr[r])
    off, on = out["off"], out["on"]
    assert off["mode"] == on["mode"]
    ratio = on["k"] / off["k"]
    predicted = (on["k_r"] / off["k_r"]) * (on["w"] * on["e"]) / (off["w"] * off["e"])
    assert ratio == pytest.approx(predicted, rel=0.02)
    assert abs(on["e"] / off["e"] - 1) > 0.05  # the joint share does change
    assert abs(ratio / (on["f"] / off["f"]) ** 3 - 1) > 0.05  # so the cube law is off


def test_paired_minimum_is_the_lowest_own_peak_of_a_paired_mode():
    fr = np.array([1000.0, 1500.0, 1520.0, 2500.0])
    pphi = np.array([0.5, 0.05, 0.3, 0.2])  # mode 1 unpaired and strong: the band minimum
    zeta = np.full(4, 0.03)
    paired = np.array([False, True, False, True])  # mode 2 lies in the half-power band of the stronger mode 3
    m = rg.band_minimum(BAND, fr, zeta, np.zeros(4), pphi, paired=paired)

    def valley(lo, hi):  # min |F/X| of the modal sum near a resonance, on a fine grid of its own
        f = np.linspace(lo, hi, 20001)
        w, wr = 2 * np.pi * f[:, None], 2 * np.pi * fr[None, :]
        return (1 / np.abs((pphi**2 / (wr**2 - w**2 + 2j * zeta * wr * w)).sum(axis=1))).min()

    assert m["mode"] == 0 and m["k_min_N_per_m"] == pytest.approx(valley(950, 1050), rel=1e-3)
    assert m["mode_paired"] == 3 and m["k_paired_N_per_m"] == pytest.approx(valley(2420, 2580), rel=1e-3)
    assert m["f_paired_Hz"] == pytest.approx(2500.0, rel=0.03)  # within its half-power band
    # the valley is not 2 zeta k_r of the mode alone: the other modes' mass lines add to the receptance
    assert m["k_paired_N_per_m"] < 0.9 * 2 * zeta[3] * (2 * np.pi * fr[3]) ** 2 / pphi[3] ** 2
    none = rg.band_minimum(BAND, fr, zeta, np.zeros(4), pphi, paired=[False, True, False, False])
    assert none["mode_paired"] is None and none["k_paired_N_per_m"] is None


def test_status_says_which_unpaired_mode_governs():
    assert status_text(4, 2088.5, "table bounce", 3) == "identified"
    assert status_text(2, 1308.07, "table bounce", 0) == ("not identified: the governing mode (FE mode 2, 1308.1 Hz, "
                                                          "table bounce) has no measured partner")


def test_range_table_takes_the_increase_case_by_case():
    def cases(k_paired, k_all):
        rows = [{"point": p, "damping_law": law, "k_paired_N_per_mm": k_paired[i, j], "k_min_N_per_mm": k_all[i, j]}
                for i, p in enumerate(["T01", "T05"]) for j, law in enumerate(rg.LAWS)]
        return pd.DataFrame(rows)

    off = cases(np.array([[100.0, 100, 100], [200, 200, 200]]), np.full((2, 3), 50.0))
    on = cases(np.array([[150.0, 130, np.nan], [180, 260, 240]]), np.full((2, 3), 40.0))
    tab = rg.range_table({"power_off": off, "power_on": on}, "power_off", "T05", {"power_on": 42.1}).set_index(
        ["basis", "over"])
    row = tab.loc[("paired modes", "points × damping laws")]
    assert row.n_cases == 5  # the case without a paired peak in one state drops out
    assert (row.increase_low_pct, row.increase_high_pct) == pytest.approx((-10.0, 50.0))
    assert (row.k_min_low_N_per_mm, row.k_min_high_N_per_mm) == (130.0, 260.0) and row.paper_inside
    at = tab.loc[("paired modes", "damping laws at T05")]
    assert (at.increase_low_pct, at.increase_high_pct) == pytest.approx((-10.0, 30.0)) and not at.paper_inside
    assert tab.loc[("all modes", "points × damping laws")].increase_high_pct == pytest.approx(-20.0)


def test_damping_ratio_range_of_a_single_mode_is_two_zeta_k():
    """One mass-normalised mode (k_r = w_r^2 at pphi = 1): min |F/X| = 2 zeta sqrt(1 - zeta^2) k_r,
    linear in zeta to O(zeta^3), so the range's ends are the range's ends of zeta."""
    f0 = 1000.0
    k = (2 * np.pi * f0) ** 2
    out = rg.damping_ratio_range((300.0, 3500.0), [f0], [0.03], [1.0], 0.0, (0.02, 0.05), n_freq=4001)
    exact = lambda z: 2 * z * np.sqrt(1 - z**2) * k  # noqa: E731
    assert out["damping_ratio_grid"][0] == 0.02 and out["damping_ratio_grid"][-1] == 0.05
    # on a grid the minimum is found from above, to the resonance grid's resolution
    for key, z in (("k_min_low_N_per_m", 0.02), ("k_min_high_N_per_m", 0.05)):
        assert exact(z) * (1 - 1e-12) <= out[key] <= exact(z) * (1 + 1e-3)
    assert out["governing_fe_mode"] == [1] * 7


def test_damping_ratio_range_keeps_measured_ratios_and_follows_each_pairing():
    """Two modes: the 1 kHz one (weaker at the drive point) keeps a measured ratio; the 2 kHz one's
    ratio runs over the range. Paired-peak ranges follow each pairing's paired modes."""
    fr, pphi = [1000.0, 2000.0], [0.5, 1.0]
    k = (2 * np.pi * np.array(fr)) ** 2 / np.array(pphi) ** 2
    out = rg.damping_ratio_range((300.0, 3500.0), fr, [0.01, 0.03], pphi, 0.0, (0.02, 0.05),
                                 fixed=[True, False], n_freq=4001,
                                 paired={"chosen": np.array([True, False]), "tied 1": np.array([False, True])})
    # mode 1: 2 * 0.01 * k1 = 0.08 k(1 kHz) ... mode 2: 2 zeta k2 with k2 = w2^2: mode 2 governs only at low zeta
    assert out["paired"]["chosen"]["k_paired_low_N_per_m"] == pytest.approx(out["paired"]["chosen"]["k_paired_high_N_per_m"],
                                                                              rel=2e-2)  # its ratio is kept
    assert out["paired"]["chosen"]["k_paired_low_N_per_m"] == pytest.approx(2 * 0.01 * k[0], rel=3e-2)
    assert out["paired"]["tied 1"]["k_paired_high_N_per_m"] / out["paired"]["tied 1"]["k_paired_low_N_per_m"] \
        == pytest.approx(0.05 / 0.02, rel=3e-2)
    assert set(out["paired"]["tied 1"]["paired_fe_mode"]) == {2}
    assert out["k_min_low_N_per_m"] == pytest.approx(min(2 * 0.01 * k[0], 2 * 0.02 * k[1]), rel=3e-2)


@pytest.mark.parametrize("bad", [(0.05, 0.02), (0.0, 0.05), (0.02, 1.0)])
def test_damping_ratio_range_must_be_an_increasing_pair_of_ratios(bad):
    from jointid.errors import ConfigError

    with pytest.raises(ConfigError, match="damping_ratio_range"):
        rg.damping_ratio_range((300.0, 3500.0), [1000.0], [0.03], [1.0], 0.0, bad)
