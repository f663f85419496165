"""Choosing among pairings of equal fit (:mod:`jointid.identification.updating`).

A clearly visible model mode left unpaired is scored against the measured mode nearest to it with
the residual that pairing it would give, so swapping it with that measured mode's partner fits
exactly alike.  Which of such tied pairings a multistart finds first is round-off; the choice among
them is made here, by rules, in this order:

1. **resolvability** (:func:`choose_tied`, :func:`could_hide`): a visible model mode that no measured
   mode takes is only admissible if the test could have merged it into a measured peak, i.e. if it
   lies inside that measured mode's half-power band, ``|f_model / f_meas - 1| <= zeta`` (the
   half-power bandwidth is ``2 zeta f``).  The pairing under which every unpaired visible mode could
   hide is preferred; a mode that could not hide must be paired.
2. when several tied pairings pass that test, or none does (or no damping ratio is known): the
   nearest partners (least summed squared log error of the paired modes), then the first pairing in
   order.  The rule that decided is returned with the choice, in words, for ``params.json`` and the
   tables.
"""

from __future__ import annotations

import numpy as np

from jointid.config.typed import Damping


TIE = 1e-12  # cost difference below which two pairings fit alike (exact ties, round-off apart)
RESOLVABILITY = "resolvability"
NEAREST = "nearest partners"
NO_TIE = "least cost (no tie)"


def least_cost_tied(options: list, cost) -> list:
    """The options whose ``cost`` lies within :data:`TIE` of the least one."""
    low = min(cost(o) for o in options)
    return [o for o in options if cost(o) < low + TIE]


def hiding_peak(f_model_Hz: float, f_meas_Hz, zeta) -> dict:
    """The measured peak a model mode at ``f_model_Hz`` comes nearest to hiding in, in units of each
    measured mode's half-power half-width.

    A mode of damping ratio ``zeta_i`` at ``f_i`` has a half-power band ``f_i (1 -+ zeta_i)`` (full
    bandwidth ``2 zeta_i f_i``); a second mode inside it merges with the peak in a frequency-only
    test.  Returns ``measured_order`` (1-based, of the measured mode of least ``offset / zeta``),
    ``measured_Hz``, ``offset`` (``|f_model / f_i - 1|``, dimensionless), ``damping_ratio``
    (``zeta_i``) and ``hides`` (``offset <= zeta_i``)."""
    f = np.asarray(f_meas_Hz, float)
    z = np.broadcast_to(np.asarray(zeta, float), f.shape)
    offset = np.abs(float(f_model_Hz) / f - 1.0)
    i = int(np.argmin(offset / z))
    return {"measured_order": i + 1, "measured_Hz": float(f[i]), "offset": float(offset[i]),
            "damping_ratio": float(z[i]), "hides": bool(offset[i] <= z[i])}


def could_hide(unpaired_Hz, f_meas_Hz, zeta) -> bool:
    """Whether every unpaired visible model mode (``unpaired_Hz``) lies inside the half-power band of
    some measured mode (:func:`hiding_peak`); True when there is none."""
    return all(hiding_peak(u, f_meas_Hz, zeta)["hides"] for u in np.atleast_1d(np.asarray(unpaired_Hz, float)))


def choose_tied(options: list, cost, paired_ss, pairing, resolvable=None) -> tuple:
    """``(option, rule)``: the option of least ``cost`` and, in words, the rule that chose it among
    the options tied with it (within :data:`TIE`).

    ``resolvable(option) -> bool`` (None: not known, e.g. no damping ratio) says whether every
    clearly visible model mode the option leaves unpaired could hide inside a measured peak
    (:func:`could_hide`).  Among the tied options the one resolvable option wins (rule
    ``"resolvability"``); if several are resolvable, or none, the nearest partners (least
    ``paired_ss``), then the first ``pairing`` in order, choose among the resolvable ones, else among
    all (rule ``"nearest partners (fallback: <why>)"``).  Without a tie the rule is
    ``"least cost (no tie)"``.
    """
    tied = least_cost_tied(options, cost)
    key = lambda o: (paired_ss(o), [int(c) for c in pairing(o)])  # noqa: E731
    if len(tied) == 1:
        return tied[0], NO_TIE
    n = len(tied)
    if resolvable is None:
        return min(tied, key=key), f"{NEAREST} (fallback: no damping ratio to judge resolvability; {n} tied pairings)"
    ok = [o for o in tied if resolvable(o)]
    if len(ok) == 1:
        return ok[0], RESOLVABILITY
    if not ok:
        return min(tied, key=key), (f"{NEAREST} (fallback: none of the {n} tied pairings lets every unpaired "
                                    "visible mode hide in a measured peak)")
    return min(ok, key=key), (f"{NEAREST} (fallback: {len(ok)} of the {n} tied pairings let every unpaired "
                              "visible mode hide in a measured peak)")


def tie_damping(n_meas: int, measured=None, damping: Damping | None = None, f_meas_Hz=None) -> tuple:
    """``(zeta per measured mode or None, source in words)``: the damping ratios the resolvability rule
    judges the half-power bands with.

    The measured damping ratio of a mode when the dataset has one (``measured``, NaN = none), else
    the configured harmonic damping: ``harmonic.damping.damping_ratio`` (model ``modal``), or the
    Rayleigh ratio ``alpha / (2 w) + beta w / 2`` at the measured frequency (model ``rayleigh``).
    A joint-dashpot model needs each mode's joint strain-energy share, not known for a measured mode:
    then (and for model ``measured`` without measured ratios) None, and the rule falls back.
    """
    d = damping or Damping()
    zeta = np.full(int(n_meas), np.nan)
    if d.model == "modal" and d.damping_ratio is not None:
        zeta[:] = float(d.damping_ratio)
        conf = f"configured harmonic.damping.damping_ratio = {float(d.damping_ratio):g}"
    elif d.model == "rayleigh" and f_meas_Hz is not None:
        w = 2 * np.pi * np.asarray(f_meas_Hz, float)
        zeta[:] = float(d.alpha_per_s or 0.0) / (2 * w) + float(d.beta_s or 0.0) * w / 2
        conf = "Rayleigh ratios of harmonic.damping at the measured frequencies"
    else:
        conf = ""
    m = np.full(int(n_meas), np.nan) if measured is None else np.asarray(measured, float)
    have = np.isfinite(m) & (m > 0)
    zeta[have] = m[have]
    if not np.all(np.isfinite(zeta) & (zeta > 0)):
        return None, f"no damping ratio for every measured mode (harmonic.damping.model {d.model!r}, no measured ratios)"
    if have.all():
        return zeta, "measured damping ratios of the dataset"
    return zeta, (f"measured damping ratios of the dataset, else the {conf}" if have.any() else f"the {conf}")


def paired_ss(res, f_meas) -> float:
    """Sum of the squared log errors of the paired modes alone (how near the partners are)."""
    return float(np.sum(np.log(np.asarray(res.f_model, float) / np.asarray(f_meas, float)) ** 2))


def tied_alternatives(candidates: list[dict], chosen, cost=lambda c: c["cost"]) -> list[list[int]]:
    """The pairings among ``candidates`` (records ``{"pairing": [...], "cost": ...}``, as
    ``params.json``'s ``joint_pairing`` keeps them) other than ``chosen`` that fit exactly as well
    (within :data:`TIE`): the fit cannot choose between them; :func:`choose_tied`'s rules do."""
    chosen = [int(c) for c in chosen]
    ref = [cost(c) for c in candidates if [int(p) for p in c["pairing"]] == chosen]
    if not ref:
        return []
    return [[int(p) for p in c["pairing"]] for c in candidates
            if [int(p) for p in c["pairing"]] != chosen and abs(cost(c) - ref[0]) < TIE]
