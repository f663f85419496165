"""The identified joint damping at work: modal damping ratios from a ``params.json["joint_damping"]`` record,
the words Table 1 states its damping with, and the comparison of the states.

The record is :func:`jointid.identification.joint_damping.stage_record`'s (written by the identify stage
only when the dataset carries damping ratios).  :func:`usable_record` says whether it can set the damping of
the model (identified, and every parameter of the better law identifiable); :func:`law_ratios` gives the
damping ratio of any mode from its joint energy shares under the better law, with a 95 % interval from the
law's covariance (the record's, at the total uncertainty: inflated by the model error when the fit sits above
the noise); :func:`states_comparison` says whether the attraction (a state against the reference state)
changes the structural ratio or a joint loss factor: the difference with its combined 95 % interval, "changes"
only when that interval excludes 0 (:func:`jointid.identification.joint_damping.attraction_change`).
"""

from __future__ import annotations

import numpy as np

from jointid.identification.joint_damping import Z95, _design, attraction_change

__all__ = ["ASSUMED", "IDENTIFIED", "MEASURED", "LOW_CUT", "law_ratios", "law_text", "states_comparison",
           "usable_record"]

ASSUMED, MEASURED, IDENTIFIED = "assumed", "measured", "identified"
"""Damping sources of a state: the configured (assumed) model; measured ratios of the paired modes copied (the
others assumed); the identified law for every elastic mode."""
LOW_CUT = 0.1
"""A mode's lower 95 % ratio is cut at this fraction of its value: a ratio <= 0 leaves a resonance unbounded."""
_FORMULA = {"hysteretic": "ζ0 + Σ_j η_j e_rj/2", "viscous": "ζ0 + Σ_j c_j ω_r e_rj/2"}


def usable_record(rec: dict | None) -> tuple[dict | None, str]:
    """``(record, note)``: the identified ``joint_damping`` record of ``params.json`` (``rec``; None: the data
    carry no damping ratios) when it can set the model's damping, else ``(None, why not)``."""
    if rec is None:
        return None, "the data carry no damping ratios: damping assumed"
    if not rec.get("identified"):
        return None, f"joint damping not identified ({rec.get('note', '')}): damping assumed"
    law = rec["law"]
    missing = [k for k in rec[law]["covariance_order"] if rec[law].get(k) is None]
    if missing:
        return None, (f"joint damping: {', '.join(missing)} of the {law} law not identifiable from the measured "
                      "modes: damping assumed")
    return rec, f"identified from {rec['n_modes']} measured damping ratios ({law} law)"


def _law(rec: dict) -> tuple[str, list[str], np.ndarray, np.ndarray]:
    law = rec["law"]
    keys = rec[law]["covariance_order"]
    return law, keys, np.array([rec[law][k] for k in keys], float), np.asarray(rec[law]["covariance"], float)


def law_ratios(rec: dict, shares, freqs_Hz) -> dict:
    """Damping ratios of modes under the record's better law.

    Parameters
    ----------
    rec : dict
        A usable ``joint_damping`` record (:func:`usable_record`).
    shares : array_like, shape (n_modes, n_dirs)
        The modes' joint energy shares ``e_rj``, columns in ``rec["directions"]`` order (dimensionless).
    freqs_Hz : array_like, shape (n_modes,)
        Their natural frequencies (Hz, elastic modes only).

    Returns
    -------
    dict
        ``zeta, zeta_low, zeta_high`` ``(n_modes,)``: the value and its 95 % interval, ``value +- 1.96 sd``
        with ``sd^2 = a_r^T C a_r`` (``a_r`` the mode's row of the law's design, ``C`` the record's
        covariance), the lower end cut at :data:`LOW_CUT` of the value; ``law``.
    """
    law, _, x, cov = _law(rec)
    A = _design(np.atleast_2d(np.asarray(shares, float)), np.asarray(freqs_Hz, float), law)
    zeta = A @ x
    sd = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", A, cov, A), 0.0))
    return {"zeta": zeta, "zeta_low": np.maximum(zeta - Z95 * sd, LOW_CUT * zeta), "zeta_high": zeta + Z95 * sd,
            "law": law}


def law_text(rec: dict) -> str:
    """``identified: ζ0 + Σ_j η_j e_rj/2 (hysteretic law; ζ0 = 0.0041 [0.0035, 0.0047], η_normal = ...)``."""
    law, keys, _, _ = _law(rec)
    r = rec[law]
    vals = "; ".join(f"{k.replace('zeta0', 'ζ0').replace('eta_', 'η_')} = {r[k]:.3g} [{r[k + '_ci95_low']:.3g}, "
                     f"{r[k + '_ci95_high']:.3g}]" for k in keys)
    return f"identified: {_FORMULA[law]} ({law} law; {vals}; 95 % intervals)"


def _state_values(rec: dict | None) -> dict:
    """One state's hysteretic values with their intervals, or why there are none."""
    if rec is None:
        return {"identified": False, "note": "the data carry no damping ratios"}
    if not rec.get("identified"):
        return {"identified": False, "note": rec.get("note", "")}
    keys = rec["hysteretic"]["covariance_order"]
    return {"identified": True, "law": rec["law"], "n_modes": rec["n_modes"],
            "intervals_inflated": rec["intervals_inflated"],
            "parameters": {k: {"value": rec.get(k), "ci95_low": rec.get(f"{k}_ci95_low"),
                               "ci95_high": rec.get(f"{k}_ci95_high")} for k in keys}}


def _comparison(off: dict, on: dict, state: str, reference: str) -> dict:
    """The hysteretic parameters of ``state`` against the reference state's."""
    ch = attraction_change(off, on)
    par = {}
    for k in off["hysteretic"]["covariance_order"]:
        d = ch.get(f"{k}_change")
        par[k] = ({"change": None, "note": "not identifiable in both states"} if d is None else
                  {"change": d, "ci95_low": ch[f"{k}_change_ci95_low"], "ci95_high": ch[f"{k}_change_ci95_high"],
                   "changes": ch[f"{k}_changed"]})
    eta = {k: v for k, v in par.items() if k.startswith("eta_")}
    changed = [k for k, v in eta.items() if v.get("changes")]
    text = (f"{state} against {reference}: the joint loss factor changes ({', '.join(changed)}: the 95 % interval "
            "of the difference excludes 0)" if changed else
            f"{state} against {reference}: no joint loss factor changes beyond its 95 % interval")
    return {"state": state, "reference_state": reference, "parameters": par,
            "eta_changes": bool(changed) if eta and all(v["change"] is not None for v in eta.values()) else None,
            "text": text}


def states_comparison(records: dict, reference: str) -> dict:
    """Does the attraction change the joint loss factor?  Each state's identified hysteretic law against the
    ``reference`` state's (``power_off``).

    Parameters
    ----------
    records : dict
        State -> its ``params.json["joint_damping"]`` record (None: the data carry no damping ratios).
    reference : str
        The state the others are compared with.

    Returns
    -------
    dict
        ``available`` (at least two states identified, the reference among them), ``reference_state``,
        ``states`` (per state its values and 95 % intervals, or why none), ``comparisons`` (per other state:
        per parameter ``change = state - reference``, its ``ci95_low/high`` (sd combined as independent
        fits: sqrt(sd_a^2 + sd_b^2)) and ``changes`` (the interval excludes 0); ``eta_changes``; ``text``),
        and a ``note``.
    """
    states = {s: _state_values(r) for s, r in records.items()}
    ok = [s for s, v in states.items() if v["identified"]]
    out = {"available": reference in ok and len(ok) >= 2, "reference_state": reference, "states": states,
           "comparisons": []}
    if not out["available"]:
        out["note"] = ("no comparison: the joint damping is identified in "
                       + (", ".join(ok) if ok else "no state") + " (two states with damping ratios are needed, "
                       f"{reference} among them)")
        return out
    out["comparisons"] = [_comparison(records[reference], records[s], s, reference) for s in ok if s != reference]
    out["note"] = "; ".join(c["text"] for c in out["comparisons"])
    return out

