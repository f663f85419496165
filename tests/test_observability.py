"""Observability of model modes in a modal test: analytic two-mass references and the visibility rule."""
import numpy as np
import pytest

from jointid.correlate.observability import (MeasurementSetup, clearly_visible, misfit_target, nearest_measured,
                                             visibility)
from jointid.correlate.pairing import ordered_assignment, pair_by_frequency


def two_masses(k1=4.0e6, k2=1.0e6, m1=2.0, m2=1.0):
    """Ground - k1 - m1 - k2 - m2: eigenpairs (mass-normalised) of the free vibration."""
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    M = np.diag([m1, m2])
    lam, phi = np.linalg.eigh(np.linalg.solve(np.sqrt(M), np.linalg.solve(np.sqrt(M), K).T).T)
    phi = np.linalg.solve(np.sqrt(M), phi)
    return K, M, np.sqrt(lam) / (2 * np.pi), phi


def test_visibility_is_the_resonance_peak_of_the_summed_frf():
    K, M, f, phi = two_masses()
    zeta = 0.01
    labels = ["A:y", "B:y"]
    setup = MeasurementSetup(excitation=("A:y",), response=("A:y", "B:y"))
    vis = visibility(phi, f, labels, setup, zeta=zeta)
    for r in range(2):  # the summed |H| at resonance r, from the full damped response (modal damping)
        w = 2 * np.pi * f[r]
        H = sum(np.outer(phi[:, s], phi[:, s]) / ((2 * np.pi * f[s]) ** 2 - w ** 2
                                                  + 2j * zeta * (2 * np.pi * f[s]) * w) for s in range(2))
        summed = np.abs(H[:, 0]).sum()
        assert vis[r] == pytest.approx(summed, rel=0.05)  # the other mode's share at this frequency is small


def test_a_mode_with_a_node_at_the_hammer_is_invisible():
    # two equal masses on equal springs to ground, coupled: the antisymmetric mode has a node in the middle
    phi = np.array([[1.0, 1.0], [1.0, 0.0], [1.0, -1.0]]) / np.sqrt(2)  # points L, C, R (y)
    f = np.array([100.0, 120.0])
    labels = ["L:y", "C:y", "R:y"]
    centre = visibility(phi, f, labels, MeasurementSetup(("C:y",), tuple(labels)))
    corner = visibility(phi, f, labels, MeasurementSetup(("L:y",), tuple(labels)))
    assert centre[1] == 0.0 and centre[0] > 0
    assert corner[1] > 0
    # the rule: paired with mode 0 only; mode 1 is clearly visible from the corner, not from the centre
    assert list(clearly_visible(corner, [0])) == [True, True]
    assert list(clearly_visible(centre, [0])) == [True, False]


def test_visibility_scales_as_one_over_omega_squared_and_ignores_unknown_labels():
    phi = np.ones((2, 2))
    vis = visibility(phi, np.array([100.0, 200.0]), ["P:x", "P:y"],
                     MeasurementSetup(("P:y", "Q:z"), ("P:x", "P:y", "Q:y")))
    assert vis[0] / vis[1] == pytest.approx(4.0)
    assert np.all(visibility(phi, np.array([100.0, 200.0]), ["P:x", "P:y"], MeasurementSetup(("Q:z",), ("P:x",))) == 0)


def test_threshold_is_relative_to_the_weakest_paired_mode():
    vis = np.array([1.0, 0.3, 0.2, 0.04, 4.0, 0.09])
    assert list(clearly_visible(vis, [0, 2])) == [True, True, True, False, True, True]  # limit 0.25 * 0.2 = 0.05
    assert list(clearly_visible(vis, [0, 2], threshold=0.5)) == [True, True, True, False, True, False]
    assert not clearly_visible(vis, []).any()
    assert not clearly_visible(vis, [-1, -1]).any()


def test_nearest_measured_in_log_distance():
    assert list(nearest_measured([100, 140, 400], [120.0, 300.0])) == [120.0, 120.0, 300.0]


def test_misfit_target_is_the_nearer_of_measured_mode_and_band_edge():
    """A mode just inside the band edge is scored against the edge (it would be unseen just outside
    it); a mode mid-band against the nearest measured mode."""
    t = misfit_target([2450.0, 3400.0, 150.0], [1000.0, 2400.0], (140.0, 3500.0))
    assert list(t) == [2400.0, 3500.0, 140.0]


def test_setup_from_spec_and_default():
    pts = ["T01", "T02"]
    s = MeasurementSetup.from_spec({"excitation": ["T01:y"], "response_directions": ["y"]}, pts, ["T02:x"])
    assert s.excitation == ("T01:y",) and s.response == ("T01:y", "T02:y")
    d = MeasurementSetup.from_spec(None, pts, ["T02:x", "T02:y", "T02:z"])
    assert d.excitation == ("T02:x", "T02:y", "T02:z") and len(d.response) == 6 and "assumed" in d.note
    m = MeasurementSetup.from_spec(None, pts, ["T02:y"], measured_labels=["T01:z"])
    assert m.response == ("T01:z",)


def test_skip_cost_makes_the_ordered_assignment_take_a_visible_mode():
    f_meas = np.array([100.0, 200.0])
    f_model = np.array([100.0, 150.0, 203.0])
    free = pair_by_frequency(f_meas, f_model)
    assert list(free) == [0, 2]  # the 150 Hz mode is skipped for free
    skip = (np.log(f_model / nearest_measured(f_model, f_meas))) ** 2 * np.array([0.0, 1.0, 0.0]) * 10
    costly = pair_by_frequency(f_meas, f_model, skip_cost=skip)
    assert list(costly) == [0, 1]  # now leaving 150 Hz unpaired costs more than pairing 200 with it
    # zero skip costs give exactly the free assignment
    cost = np.random.default_rng(1).random((3, 6))
    assert list(ordered_assignment(cost)) == list(ordered_assignment(cost, skip_cost=np.zeros(6)))


def test_skip_cost_assignment_is_the_brute_force_optimum():
    from itertools import combinations

    rng = np.random.default_rng(7)
    for _ in range(30):
        m, n = 3, 6
        cost, skip = rng.random((m, n)), rng.random(n)
        cols = ordered_assignment(cost, skip_cost=skip)
        total = lambda c: cost[range(m), list(c)].sum() + skip[[j for j in range(n) if j not in c]].sum()  # noqa: E731
        best = min(total(c) for c in combinations(range(n), m))
        assert total(cols) == pytest.approx(best)


def test_shared_state_pairing_sums_the_skip_costs_of_every_state_along_the_tracks():
    from jointid.correlate.pairing import pair_states_by_frequency

    f_meas = [np.array([100.0, 200.0]), np.array([110.0, 220.0])]
    f_model = [np.array([100.0, 150.0, 203.0]), np.array([165.0, 110.0, 223.0])]  # state 2 reorders
    tracks = [np.array([0, 1, 2]), np.array([1, 0, 2])]
    free = pair_states_by_frequency(f_meas, f_model, tracks)
    assert [list(p.model_index) for p in free] == [[0, 2], [1, 2]]
    # the 150/165 Hz mode is clearly visible in both states: leaving it unpaired now costs its misfit
    skips = [np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])]
    costly = pair_states_by_frequency(f_meas, f_model, tracks, skip_cost=skips)
    assert [list(p.model_index) for p in costly] == [[0, 1], [1, 0]]
    # one state's cost alone (half as large) does not outweigh the pairing error of both states
    small = [np.array([0.0, 0.01, 0.0]), np.zeros(3)]
    assert [list(p.model_index) for p in pair_states_by_frequency(f_meas, f_model, tracks, skip_cost=small)] \
        == [[0, 2], [1, 2]]


def test_mac_uses_the_locations_both_shapes_have():
    """A location missing for one mode only leaves the other modes' pairs on every location, and a
    mode without any shape has MAC 0 with everything (it poisons nothing)."""
    from jointid.correlate.mac import mac

    rng = np.random.default_rng(0)
    a = rng.standard_normal((6, 3))
    b = rng.standard_normal((6, 4))
    full = mac(a, b)
    a2 = a.copy()
    a2[0, 1] = np.nan          # mode 2 lacks location 1
    a2[:, 2] = np.nan          # mode 3 has no shape at all
    m = mac(a2, b)
    assert np.allclose(m[0], full[0])                       # untouched mode: all locations
    assert np.allclose(m[1], mac(a[1:, 1], b[1:])[0])       # its own common locations
    assert np.all(m[2] == 0.0)


def test_a_mode_without_a_shape_is_paired_by_frequency():
    from jointid.correlate.pairing import pair_modes

    f_model = np.array([100.0, 200.0, 300.0, 400.0])
    shapes_model = np.eye(4)
    f_meas = np.array([101.0, 199.0, 305.0])
    meas = np.eye(4)[:, [0, 1, 2]].copy()
    meas[:, 2] = np.nan        # the third measured mode's shape is missing
    p = pair_modes(f_meas, f_model, meas, shapes_model)
    assert list(p.model_index) == [0, 1, 2] and p.unpaired_measured == []
