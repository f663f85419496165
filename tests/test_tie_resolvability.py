"""The resolvability rule among exactly tied pairings (jointid.identification.ties), on analytic numbers.

A measured peak at f_i with damping ratio zeta_i has the half-power band f_i (1 -+ zeta_i): a model mode
inside it merges with the peak in a frequency-only test, one outside it would show as a peak of its own.
"""

import numpy as np

from jointid.config.typed import Damping
import pytest

from jointid.identification.ties import (NO_TIE, RESOLVABILITY, choose_tied, could_hide, hiding_peak,
                                         tie_damping)

F_MEAS = np.array([344.0, 1416.0, 1503.0])


def test_a_mode_hides_only_inside_the_half_power_band():
    # 1416 Hz at zeta 0.03: band 1373.5 .. 1458.5 Hz
    assert hiding_peak(1414.6, F_MEAS, 0.03) == {"measured_order": 2, "measured_Hz": 1416.0,
                                                 "offset": pytest.approx(1.4 / 1416), "damping_ratio": 0.03,
                                                 "hides": True}
    bounce = hiding_peak(1314.0, F_MEAS, 0.03)  # -7.2 %: outside every band
    assert bounce["measured_order"] == 2 and not bounce["hides"]
    assert bounce["offset"] == pytest.approx(102.0 / 1416)
    assert hiding_peak(1416 * 0.9701, F_MEAS, 0.03)["hides"] and not hiding_peak(1416 * 0.9699, F_MEAS, 0.03)["hides"]
    # per measured mode: a wider peak at 1503 Hz (zeta 0.08) takes a mode at 1400 Hz (-6.9 %) that 1416 Hz cannot
    wide = hiding_peak(1400.0, F_MEAS, [0.03, 0.01, 0.08])
    assert wide["measured_order"] == 3 and wide["hides"] and wide["damping_ratio"] == 0.08


def test_could_hide_needs_every_unpaired_mode_to_hide():
    assert could_hide([], F_MEAS, 0.03)  # nothing unpaired
    assert could_hide([1414.6], F_MEAS, 0.03)
    assert not could_hide([1414.6, 1314.0], F_MEAS, 0.03)
    assert could_hide([1414.6, 1314.0], F_MEAS, 0.08)  # at 8 % damping the bounce merges too


def _options():
    """Two pairings tied exactly: A leaves the bounce (1314 Hz) unpaired and pairs the yaw (1414.6 Hz)
    with 1416 Hz (nearer partners), B the reverse."""
    return [{"name": "A", "cost": 1.0, "ss": 0.001, "pairing": [0, 2, 3], "unpaired": [1314.0]},
            {"name": "B", "cost": 1.0, "ss": 0.006, "pairing": [0, 1, 3], "unpaired": [1414.6]},
            {"name": "C", "cost": 2.0, "ss": 0.0, "pairing": [0, 1, 2], "unpaired": []}]


def _choose(options, zeta):
    hide = None if zeta is None else (lambda o: could_hide(o["unpaired"], F_MEAS, zeta))
    o, how = choose_tied(options, lambda o: o["cost"], lambda o: o["ss"], lambda o: o["pairing"], hide)
    return o["name"], how


def test_resolvability_pairs_the_mode_that_could_not_hide():
    assert _choose(_options(), 0.03) == ("B", RESOLVABILITY)  # not the nearest partners (A)


def test_fallbacks_say_why():
    name, how = _choose(_options(), 0.08)  # both hide: nearest partners among them
    assert name == "A" and how == "nearest partners (fallback: 2 of the 2 tied pairings let every unpaired visible mode hide in a measured peak)"
    name, how = _choose(_options(), 0.0005)  # neither hides (the yaw is 0.1 % off)
    assert name == "A" and how.startswith("nearest partners (fallback: none of the 2 tied pairings")
    name, how = _choose(_options(), None)
    assert name == "A" and how.startswith("nearest partners (fallback: no damping ratio")
    # equal partners too: the first pairing in order
    eq = [dict(o, ss=0.001) for o in _options()]
    assert _choose(eq, 0.08)[0] == "B"  # [0, 1, 3] < [0, 2, 3]


def test_no_tie_no_rule():
    opts = _options()
    opts[1]["cost"] = 1.0 + 1e-9  # beyond the tie tolerance
    assert _choose(opts, 0.03) == ("A", NO_TIE)


def test_tie_damping_measured_else_configured():
    z, src = tie_damping(3, None, Damping(model="modal", damping_ratio=0.03))
    assert z.tolist() == [0.03] * 3 and "damping_ratio = 0.03" in src
    z, src = tie_damping(3, [0.02, np.nan, 0.05], Damping(model="modal", damping_ratio=0.03))
    assert z.tolist() == [0.02, 0.03, 0.05] and src.startswith("measured damping ratios of the dataset, else")
    z, src = tie_damping(3, [0.02, 0.04, 0.05], Damping(model="joint", joint_loss_factor_s=1e-5))
    assert z.tolist() == [0.02, 0.04, 0.05] and src == "measured damping ratios of the dataset"
    z, _ = tie_damping(1, None, Damping(model="rayleigh", alpha_per_s=10.0, beta_s=1e-6), [1000.0])
    w = 2 * np.pi * 1000.0
    assert z[0] == pytest.approx(10.0 / (2 * w) + 1e-6 * w / 2)
    z, src = tie_damping(3, None, Damping(model="joint", joint_loss_factor_s=1e-5))
    assert z is None and "no damping ratio" in src
