"""Choosing among pairings of equal fit (:mod:`jointid.identification.updating`).

A clearly visible model mode left unpaired is scored against the measured mode nearest to it with
the residual that pairing it would give, so swapping it with that measured mode's partner fits
exactly alike.  Which of such tied pairings a multistart finds first is round-off; the choice among
them is made here, by a rule: the nearest partners, then the first pairing in order.
"""

from __future__ import annotations

import numpy as np


TIE = 1e-12  # cost difference below which two pairings fit alike (exact ties, round-off apart)


def least_cost_tied(options: list, cost) -> list:
    """The options whose ``cost`` lies within :data:`TIE` of the least one."""
    low = min(cost(o) for o in options)
    return [o for o in options if cost(o) < low + TIE]


def least_cost_nearest(options: list, cost, paired_ss, pairing):
    """The option of least ``cost``; among those tied with it (within 1e-12: a visible mode paired or
    left a misfit against the same measured mode costs the same) the one of nearest partners (least
    ``paired_ss``), then the first ``pairing`` in order, so the choice does not depend on which tied
    pairing a multistart happened to find first."""
    return min(least_cost_tied(options, cost), key=lambda o: (paired_ss(o), [int(c) for c in pairing(o)]))


def paired_ss(res, f_meas) -> float:
    """Sum of the squared log errors of the paired modes alone (how near the partners are)."""
    return float(np.sum(np.log(np.asarray(res.f_model, float) / np.asarray(f_meas, float)) ** 2))


def tied_alternatives(candidates: list[dict], chosen, cost=lambda c: c["cost"]) -> list[list[int]]:
    """The pairings among ``candidates`` (records ``{"pairing": [...], "cost": ...}``, as
    ``params.json``'s ``joint_pairing`` keeps them) other than ``chosen`` that fit exactly as well
    (within :data:`TIE`): the choice between them is the rule's, not the data's."""
    chosen = [int(c) for c in chosen]
    ref = [cost(c) for c in candidates if [int(p) for p in c["pairing"]] == chosen]
    if not ref:
        return []
    return [[int(p) for p in c["pairing"]] for c in candidates
            if [int(p) for p in c["pairing"]] != chosen and abs(cost(c) - ref[0]) < TIE]
