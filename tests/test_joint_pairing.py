"""One pairing of measured and tracked modes for all frequency-only states
(jointid.identification.updating.identify_states_jointly)."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.identification import doe
from jointid.identification.surface import fit_surface
from jointid.identification.updating import identify_state, identify_states_jointly

NAMES = ["k_normal_N_per_m3", "k_feed_N_per_m3"]
LOWER = np.array([2e11, 3e9])
UPPER = np.array([4e12, 6e10])


def four_modes(theta):
    """Four model modes; the middle two (a normal-dominated and a feed-dominated one) lie close."""
    kn, kf = theta[..., 0] / 1e12, theta[..., 1] / 1e10
    return np.stack([400.0 * kf ** 0.25, 1300.0 * kn ** 0.2, 1400.0 * kf ** 0.2,
                     2100.0 * (kn * kf) ** 0.1], axis=-1)


def _doc():
    X = doe.design("ccf", 2, n_center=1)
    Y = np.log(four_modes(doe.to_physical(X, LOWER, UPPER)))
    return {"names": NAMES, "surface": fit_surface(X, Y).to_dict(), "tracked_modes": [1, 2, 3, 4],
            "lower": LOWER.tolist(), "upper": UPPER.tolist()}


KW = dict(n_starts=4, seed=0)


def test_states_of_one_pairing_keep_it_and_their_parameters():
    doc = _doc()
    truth = {"off": np.array([5e11, 8e9]), "on": np.array([9e11, 8e9])}
    f = {s: four_modes(t)[[0, 1, 3]] for s, t in truth.items()}  # the test misses tracked mode 3
    pairing, info = identify_states_jointly(doc, f, LOWER, UPPER, **KW)
    assert list(pairing) == [0, 1, 3]
    assert info["off"]["own"] == info["on"]["own"] == [0, 1, 3]
    assert info["candidates"][0]["pairing"] == [0, 1, 3]
    for s, t in truth.items():
        res, p, _ = identify_state(doc, f[s], LOWER, UPPER, pairing=pairing, **KW)
        np.testing.assert_allclose(res.theta, t, rtol=0.02)  # quadratic surface over a factor 20


def test_the_shared_pairing_minimises_the_summed_cost_over_every_candidate():
    doc = _doc()
    # state "a" alone is closest to tracked mode 2 for its second mode, state "b" to mode 3
    f = {"a": np.array([390.0, 1330.0, 2050.0]), "b": np.array([430.0, 1420.0, 2150.0])}
    pairing, info = identify_states_jointly(doc, f, LOWER, UPPER, **KW)
    assert info["a"]["own"] != info["b"]["own"]  # on their own they disagree
    cands = info["candidates"]
    assert [c["cost"] for c in cands] == sorted(c["cost"] for c in cands)
    assert cands[0]["pairing"] == list(pairing)
    assert {tuple(info[s]["own"]) for s in f} <= {tuple(c["pairing"]) for c in cands}
    for s in f:  # the shared pairing costs each state at least its own best one
        own = identify_state(doc, f[s], LOWER, UPPER, **KW)[0].cost
        shared = identify_state(doc, f[s], LOWER, UPPER, pairing=pairing, **KW)[0].cost
        assert shared >= own - 1e-12
        assert info[s]["cost"] == pytest.approx(shared, rel=1e-9)
    total = sum(info[s]["cost"] for s in f)
    assert total == pytest.approx(cands[0]["cost"], rel=1e-9)


def test_a_given_pairing_is_kept():
    doc = _doc()
    f = four_modes(np.array([5e11, 8e9]))[[0, 1, 3]]
    _, p, _ = identify_state(doc, f, LOWER, UPPER, pairing=[0, 2, 3], **KW)
    assert list(p) == [0, 2, 3]


def _info(chi2_a, chi2_b):
    """Two candidate pairings of two states (sigma = 1, so cost = chi2)."""
    cands = [{"pairing": [0, 1, 3], "chi2_by_state": {"off": chi2_a[0], "on": chi2_a[1]}},
             {"pairing": [0, 2, 3], "chi2_by_state": {"off": chi2_b[0], "on": chi2_b[1]}}]
    for c in cands:
        c["chi2"] = sum(c["chi2_by_state"].values())
    cands.sort(key=lambda c: c["chi2"])
    return {"off": {"own": [0, 1, 3] if chi2_a[0] <= chi2_b[0] else [0, 2, 3]},
            "on": {"own": [0, 1, 3] if chi2_a[1] <= chi2_b[1] else [0, 2, 3]}, "candidates": cands}


DOC = {"names": NAMES, "tracked_modes": [1, 2, 3, 4]}


def test_notes_name_a_competing_pairing_only_when_it_fits_about_as_well():
    from jointid.stages.identify import pairing_notes as _pairing_notes

    close = _info((1.0, 1.0), (2.0, 2.5))  # 1 dof per state: delta chi2 1 and 1.5
    far = _info((1.0, 1.0), (9.0, 9.0))
    for rule in ("independent", "shared"):
        shared = close["candidates"][0]["pairing"]
        assert any(n.startswith("ambiguous pairing") for n in _pairing_notes(DOC, "off", ["off", "on"], shared,
                                                                              close, rule))
        assert not _pairing_notes(DOC, "off", ["off", "on"], far["candidates"][0]["pairing"], far, rule)


def test_notes_say_when_a_state_on_its_own_pairs_otherwise():
    from jointid.stages.identify import pairing_notes as _pairing_notes

    info = _info((1.0, 30.0), (20.0, 2.0))  # "off" prefers [0, 1, 3], "on" [0, 2, 3]; summed: [0, 2, 3]
    shared = info["candidates"][0]["pairing"]
    assert shared == [0, 2, 3]
    ind = _pairing_notes(DOC, "off", ["off", "on"], shared, info, "independent")
    assert any("measured mode(s) 2 pair with other tracked modes here ([1, 2, 4])" in n for n in ind), ind
    sh = _pairing_notes(DOC, "off", ["off", "on"], shared, info, "shared")
    assert any("on its own this state would pair" in n and "[1, 2, 4] instead of [1, 3, 4]" in n for n in sh), sh
    assert not any("on its own" in n for n in _pairing_notes(DOC, "on", ["off", "on"], shared, info, "shared"))


def _rule():
    from jointid.correlate.observability import MeasurementSetup
    from jointid.identification.visibility import VisibilityRule

    return VisibilityRule(MeasurementSetup(("P:y",), ("P:y", "Q:y")), ("P:y", "Q:y"), (300.0, 3500.0))


@pytest.mark.parametrize("seen", [False, True])
def test_a_mode_the_test_would_have_seen_is_a_misfit_not_a_free_skip(seen):
    doc = _doc()
    # tracked mode 3 (index 2) shows at the sensor only when ``seen``
    doc["ref_shapes"] = [[1.0, 1.0, 1.0 if seen else 1e-4, 1.0], [0.5, 0.5, 0.5 if seen else 0.0, 0.5]]
    truth = np.array([5e11, 8e9])
    f = four_modes(truth)[[0, 1, 3]]  # the test shows three modes; tracked mode 3 is not among them
    free, p_free, _ = identify_state(doc, f, LOWER, UPPER, **KW)
    res, p, _ = identify_state(doc, f, LOWER, UPPER, rule=_rule(), **KW)
    if not seen:  # an invisible mode may be skipped: the same fit as without the rule
        assert list(p) == list(p_free) == [0, 1, 3]
        np.testing.assert_allclose(res.theta, free.theta, rtol=1e-6)
        assert res.residuals.size == 3
    else:  # skipping it costs its distance to the nearest measured mode: the fit can no longer be exact
        assert res.cost > 100 * max(free.cost, 1e-12)
        misfit = res.residuals[3:] if res.residuals.size > 3 else np.zeros(0)
        paired_it = 2 in list(p)
        assert paired_it or misfit.size == 1, (p, res.residuals)


def _seen_doc():
    doc = _doc()
    doc["ref_shapes"] = [[1.0, 1.0, 1.0, 1.0], [0.5, 0.5, 0.5, 0.5]]  # every tracked mode shows
    return doc


def test_a_visible_unpaired_mode_suggests_the_swap_with_the_partner_of_its_target():
    from jointid.identification.updating import misfit_swaps

    doc = _seen_doc()
    f = four_modes(np.array([5e11, 8e9]))[[0, 1, 3]]
    x = doe.to_coded(np.array([5e11, 8e9]), LOWER, UPPER)
    # paired with tracked mode 2, measured mode 2 leaves tracked mode 3 unpaired and scored against it
    assert misfit_swaps(doc, (0, 1, 3), x, f, _rule()) == [(0, 2, 3)]
    assert misfit_swaps(doc, (0, 2, 3), x, f, _rule()) == [(0, 1, 3)]
    assert misfit_swaps(doc, (0, 1, 3), x, f, None) == []  # without a visibility rule: no misfits


def test_the_shared_pairing_does_not_depend_on_which_swap_the_starts_found(monkeypatch):
    from jointid.identification import updating

    doc = _seen_doc()
    truth = {"off": np.array([5e11, 8e9]), "on": np.array([9e11, 8e9])}
    f = {s: four_modes(t)[[0, 1, 3]] for s, t in truth.items()}
    rules = {s: _rule() for s in f}
    ref_pairing, ref_info = identify_states_jointly(doc, f, LOWER, UPPER, rule=rules, **KW)
    assert {(0, 1, 3), (0, 2, 3)} <= {tuple(c["pairing"]) for c in ref_info["candidates"]}
    real = updating.identify_state
    for only in [(0, 1, 3), (0, 2, 3)]:
        def one_found(*args, candidates=None, only=only, **kw):  # a multistart that found one pairing only
            out = real(*args, candidates=candidates, **kw)
            if candidates is not None:
                candidates[:] = [(only, 0.0)]
            return out

        monkeypatch.setattr(updating, "identify_state", one_found)
        pairing, info = identify_states_jointly(doc, f, LOWER, UPPER, rule=rules, **KW)
        assert list(pairing) == list(ref_pairing)
        assert info["candidates"][0]["cost"] == pytest.approx(ref_info["candidates"][0]["cost"], rel=1e-12)


@pytest.mark.parametrize("truth", [[5e11, 8e9], [9e11, 8e9], [2e12, 5e9]])
def test_one_state_takes_the_nearest_partner_among_tied_pairings(truth):
    doc = _seen_doc()
    f = four_modes(np.array(truth))[[0, 1, 3]]
    fits = {q: identify_state(doc, f, LOWER, UPPER, rule=_rule(), pairing=list(q), **KW)[0]
            for q in [(0, 1, 3), (0, 2, 3)]}
    assert fits[(0, 1, 3)].cost == pytest.approx(fits[(0, 2, 3)].cost, rel=1e-9)  # an exact tie
    nearest = min(fits, key=lambda q: np.sum(np.log(fits[q].f_model / f) ** 2))
    _, p, _ = identify_state(doc, f, LOWER, UPPER, rule=_rule(), **KW)
    assert tuple(int(c) for c in p) == nearest


@pytest.mark.parametrize("truth", [[5e11, 8e9], [2e12, 5e9]])
def test_resolvability_pairs_the_mode_that_could_not_hide_in_a_measured_peak(truth):
    """Of two exactly tied pairings the visible mode left unpaired lies at the same two distances from
    measured mode 2, swapped: a damping ratio between them lets only one of them hide in that peak's
    half-power band, so that pairing wins though its partners are not the nearest."""
    from jointid.identification.ties import NEAREST, RESOLVABILITY

    doc = _seen_doc()
    f = four_modes(np.array(truth))[[0, 1, 3]]
    fits = {q: identify_state(doc, f, LOWER, UPPER, rule=_rule(), pairing=list(q), **KW)[0]
            for q in [(0, 1, 3), (0, 2, 3)]}
    nearest = min(fits, key=lambda q: np.sum(np.log(fits[q].f_model / f) ** 2))
    other = ({(0, 1, 3), (0, 2, 3)} - {nearest}).pop()
    # the mode ``nearest`` leaves unpaired is the one ``other`` pairs with measured mode 2, and vice versa
    off = {q: abs(fits[q].f_model[1] / f[1] - 1) for q in fits}
    assert off[other] > off[nearest]  # the nearest partners leave the farther mode unpaired
    zeta = np.array([0.03, (off[nearest] + off[other]) / 2, 0.03])  # only the nearer mode hides at mode 2
    decision = {}
    _, p, _ = identify_state(doc, f, LOWER, UPPER, rule=_rule(), damping=zeta, decision=decision, **KW)
    assert tuple(int(c) for c in p) == other and decision["rule"] == RESOLVABILITY
    by = {tuple(t["pairing"]): t for t in decision["tied"]}
    assert by[other]["resolvable"] and not by[nearest]["resolvable"]
    assert by[nearest]["damping_ratio_needed"] == pytest.approx(off[other], rel=1e-6)
    # too little damping for either to hide: the nearest partners, and the record says why
    decision = {}
    _, p, _ = identify_state(doc, f, LOWER, UPPER, rule=_rule(), damping=np.full(3, 1e-4), decision=decision, **KW)
    assert tuple(int(c) for c in p) == nearest
    assert decision["rule"].startswith(NEAREST + " (fallback: none of the 2 tied pairings")


def test_the_shared_pairing_follows_resolvability_in_every_state():
    from jointid.identification.ties import RESOLVABILITY

    doc = _seen_doc()
    truth = {"off": np.array([5e11, 8e9]), "on": np.array([9e11, 8e9])}
    f = {s: four_modes(t)[[0, 1, 3]] for s, t in truth.items()}
    rules = {s: _rule() for s in f}
    near, info = identify_states_jointly(doc, f, LOWER, UPPER, rule=rules, **KW)
    assert info["tie_rule"]["rule"].startswith("nearest partners (fallback: no damping ratio")
    tied = info["tie_rule"]["tied"]
    assert len(tied) == 2 and all(t["resolvable"] is None for t in tied)
    # a damping ratio between the two pairings' needs: only the pairing that needs less is admissible
    need = {tuple(t["pairing"]): t["damping_ratio_needed"] for t in tied}
    assert need[tuple(near)] > min(need.values())  # the nearest partners leave the farther modes unpaired
    zeta = sum(need.values()) / 2
    pairing, info = identify_states_jointly(doc, f, LOWER, UPPER, rule=rules, damping={s: np.full(3, zeta) for s in f},
                                            **KW)
    assert tuple(pairing) == min(need, key=need.get) != tuple(near)
    assert info["tie_rule"]["rule"] == RESOLVABILITY
    for t in info["tie_rule"]["tied"]:
        assert {m["state"] for m in t["unpaired_visible"]} == set(f)  # the modes of every state are judged
        assert t["resolvable"] == all(abs(m["offset_pct"]) / 100 <= zeta for m in t["unpaired_visible"])


def test_each_states_own_pairing_is_a_candidate_even_when_its_search_did_not_list_it(monkeypatch):
    """A state's own best pairing need not be among the pairings its search lists (with a visibility
    rule it was not, on the coarse test run): it is fitted in every state all the same, so the
    independent rule's notes have its cost (they raised a KeyError before)."""
    import jointid.identification.updating as upd
    from jointid.stages.identify import pairing_notes

    real = upd.identify_state

    def unlisted(doc, f, lower, upper, *, candidates=None, **kw):
        out = real(doc, f, lower, upper, candidates=candidates, **kw)
        if candidates is not None:
            candidates.clear()  # the search lists none of the pairings it met
        return out

    monkeypatch.setattr(upd, "identify_state", unlisted)
    monkeypatch.setattr(upd, "misfit_swaps", lambda *a, **k: set())  # no swap brings it back either
    doc = _doc()
    f = {"a": np.array([390.0, 1330.0, 2050.0]), "b": np.array([430.0, 1420.0, 2150.0])}
    pairing, info = upd.identify_states_jointly(doc, f, LOWER, UPPER, **KW)
    assert {tuple(info[s]["own"]) for s in f} <= {tuple(c["pairing"]) for c in info["candidates"]}
    for s in f:
        pairing_notes(doc, s, list(f), pairing, info, "independent")


def test_a_fit_asked_again_with_the_same_memo_is_not_run_again(monkeypatch):
    """identify_state's memo: the same pairing (and misfit set) of the same state is fitted once; the
    joint pairing gives the same answer as when every fit is run afresh."""
    from jointid.identification import updating

    doc = _doc()
    f = {"a": np.array([390.0, 1330.0, 2050.0]), "b": np.array([430.0, 1420.0, 2150.0])}
    calls = []
    real = updating.identify
    monkeypatch.setattr(updating, "identify", lambda *a, **k: calls.append(1) or real(*a, **k))
    memo: dict = {}
    first = identify_state(doc, f["a"], LOWER, UPPER, pairing=[0, 1, 3], memo=memo, **KW)
    n_first = len(calls)
    again = identify_state(doc, f["a"], LOWER, UPPER, pairing=[0, 1, 3], memo=memo, **KW)
    assert n_first >= 1 and len(calls) == n_first  # answered from the memo
    assert again[0] is first[0] and list(again[1]) == list(first[1])
    other = identify_state(doc, f["a"], LOWER, UPPER, pairing=[0, 2, 3], memo=memo, **KW)
    assert len(calls) > n_first and other[0].cost != first[0].cost  # another pairing is fitted
    # the joint pairing with its memos, against the same search with every fit run afresh
    calls.clear()
    pairing, info = identify_states_jointly(doc, f, LOWER, UPPER, **KW)
    n_memo = len(calls)
    monkeypatch.setattr(updating, "identify_state",
                        lambda *a, memo=None, **k: identify_state(*a, **k))  # no memo: every fit runs
    calls.clear()
    pairing0, info0 = updating.identify_states_jointly(doc, f, LOWER, UPPER, **KW)
    assert len(calls) > n_memo
    assert list(pairing) == list(pairing0)
    assert [(c["pairing"], c["cost"]) for c in info["candidates"]] == \
        [(c["pairing"], c["cost"]) for c in info0["candidates"]]
