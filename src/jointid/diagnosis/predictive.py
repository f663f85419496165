"""Leave-one-mode-out prediction: does a second effect predict the modes it was not fitted to?

A pair of effects always fits at least as well as either of its singles, and with ten or so pairs tried
the best of them is chosen: its gain in chi-square is partly the selection (Yao, Vehtari, Simpson and
Gelman 2018: when no candidate is exactly true, judge models by prediction).  Here every measured mode
(its frequency rows in every state and its shape rows) is left out in turn and predicted by the fit to
the others.  The score is the log predictive density of the left-out rows, exact for a linear Gaussian
model with the parameters' uncertainty in the prediction (Cook and Weisberg 1982 for the deleted
residual): with ``z`` the whitened residuals, ``H`` the hat matrix of the whitened Jacobian and ``g`` the
mode's rows,

    -2 log p(z_g | z_-g) = z_g^T (I - H_gg)^-1 z_g - log det(I - H_gg) + const.

The rows are whitened at the diagnosis's total uncertainty (stated noise, the mesh's known error, the
model error).  Unlike the squared deleted residual, this score does not explode where a mode carries
most of a parameter: the prediction is then uncertain and says so.

A pair leads its own single only when it predicts the left-out modes better than the single does
(:func:`prediction_gain` negative).  A second effect that rests on one mode alone cannot do so: with
that mode left out its parameter is free (``I - H_gg`` singular: ``inf``) or poorly known.  Such an
effect may be real, but the data cannot confirm it by prediction; the verdict says so and names the
single.
"""

from __future__ import annotations

import numpy as np

from jointid.diagnosis.results import Fit, whitener
from jointid.identification.model_error import ModelError

__all__ = ["check_pairs", "mode_groups", "leave_one_mode_out", "prediction_gain"]

_SINGULAR = 1e-8  # 1 - h below this: the group alone determines a parameter (no prediction without it)


def mode_groups(rows: list) -> dict:
    """Row numbers of each measured mode over all states (its frequency rows ``(state, m)`` and its
    shape rows ``(state, -m)``); an unpaired visible model mode's row ``(state, 0)`` is a group of its
    own, keyed by its state and its order there."""
    groups: dict = {}
    seen: dict = {}
    for k, (si, m) in enumerate(rows):
        if m != 0:
            groups.setdefault(abs(int(m)), []).append(k)
        else:
            j = seen[si] = seen.get(si, -1) + 1
            groups[("misfit", si, j)] = [k]
    return groups


def leave_one_mode_out(f: Fit, data, me: ModelError) -> dict:
    """Per mode group (:func:`mode_groups`): ``-2 log`` of the predictive density of that mode's rows by
    the fit without it (the module doc; the constant left out); ``inf`` where the group alone
    determines a parameter."""
    A = whitener(f.ev, data, me)
    z, G = A @ f.ev.r, A @ f.ev.J
    H = G @ np.linalg.pinv(G.T @ G) @ G.T
    out = {}
    for key, idx in mode_groups(f.ev.rows).items():
        idx = np.asarray(idx)
        I_H = np.eye(len(idx)) - H[np.ix_(idx, idx)]
        if np.linalg.eigvalsh(0.5 * (I_H + I_H.T)).min() < _SINGULAR:
            out[key] = np.inf
            continue
        out[key] = float(z[idx] @ np.linalg.solve(I_H, z[idx]) - np.linalg.slogdet(I_H)[1])
    return out


def prediction_gain(big: Fit, small: Fit, data, me: ModelError) -> tuple[float, float]:
    """``(delta, se)``: the leave-one-mode-out score (:func:`leave_one_mode_out`) of ``big`` less that of
    ``small``, summed over the modes both fit (negative: ``big`` predicts better), and the standard error
    of that sum from its per-mode spread.  A mode that only ``small`` predicts (``big`` infinite) makes
    ``delta`` ``inf``; modes neither predicts are left out."""
    return _compare(leave_one_mode_out(big, data, me), leave_one_mode_out(small, data, me))[:2]


def _compare(b: dict, a: dict) -> tuple[float, float, object]:
    """``(delta, se, worst mode)`` from the per-mode scores of the larger (``b``) and smaller (``a``) fits:
    :func:`prediction_gain` and the mode whose prediction the larger fit worsens most (None when it
    worsens none)."""
    d, keys = [], []
    for key in sorted(a.keys() & b.keys(), key=str):
        if np.isinf(a[key]) and np.isinf(b[key]):
            continue
        if np.isinf(b[key]):
            return np.inf, np.inf, key
        d.append(b[key] - a[key])
        keys.append(key)
    if not d:
        return 0.0, 0.0, None
    d = np.asarray(d)
    worst = keys[int(np.argmax(d))] if d.max() > 0 else None
    return float(d.sum()), float(np.sqrt(len(d) * d.var())), worst


def check_pairs(combos: list[dict], fits: dict, data, me: ModelError) -> None:
    """Fill each pair's row (naming ``effects`` ``a+b``) with its prediction against each of its singles
    that was refitted (:func:`prediction_gain`), the worse of the two kept: ``predicts`` (the pair
    predicts the left-out modes better than every single it extends), ``prediction_delta``,
    ``prediction_se``, ``prediction_vs`` (the single compared) and, for the mode whose prediction the
    pair worsens most, ``prediction_worst_mode`` (its number; 0 for none or an unpaired model mode) with
    the two fits' prediction errors there (``prediction_worst_pair``, ``prediction_worst_single``)."""
    cache: dict = {}

    def score(label):
        if label not in cache:
            cache[label] = leave_one_mode_out(fits[label], data, me)
        return cache[label]

    for row in combos:
        a, b = str(row["effects"]).split("+")
        pair = "+" + str(row["effects"])
        worst = None
        for single in ("+" + a, "+" + b):
            if single in fits:
                delta, se, mode = _compare(score(pair), score(single))
                if worst is None or delta > worst[0]:
                    worst = (delta, se, single, mode)
        row.update({"predicts": True, "prediction_delta": np.nan, "prediction_se": np.nan, "prediction_vs": "",
                    "prediction_worst_mode": 0, "prediction_worst_pair": np.nan, "prediction_worst_single": np.nan})
        if worst is None:
            continue
        delta, se, single, mode = worst
        row.update({"predicts": bool(delta < 0), "prediction_delta": delta, "prediction_se": se,
                    "prediction_vs": single[1:]})
        if isinstance(mode, int):
            row.update({"prediction_worst_mode": mode, "prediction_worst_pair": score(pair)[mode],
                        "prediction_worst_single": score(single)[mode]})
