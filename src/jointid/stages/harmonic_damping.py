"""The damping of rule ``harmonic``: which ratio each mode gets, from where, and Table 1's range over it.

* **identified** (the dataset carries damping ratios and the identify stage identified the joint damping,
  :func:`jointid.identification.damping_law.usable_record`): every elastic mode of the band gets the
  identified law's ratio from its joint energy shares per direction at the identified parameters
  (:func:`jointid.synthetic.generate.joint_shares`); Table 1's range is the band minimum at the lower and upper
  ends of every mode's 95 % ratio interval (:func:`jointid.identification.damping_law.law_ratios`);
* **measured** (ratios in the dataset, no usable identification): the configured model, the measured ratios
  of the paired modes copied over it (as before the identification existed);
* **assumed** (frequency-only data, the paper's): the configured model (``harmonic.damping``), and Table 1's
  range over ``harmonic.damping.damping_ratio_range``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from typing import TYPE_CHECKING

from jointid import io
from jointid.identification.damping_law import ASSUMED, IDENTIFIED, MEASURED, law_ratios, law_text, usable_record
from jointid.response.drive_point import modal_damping_ratios
from jointid.response.harmonic import RIGID_HZ
from jointid.response.ranges import damping_ratio_range, damping_vectors_range

if TYPE_CHECKING:
    from jointid.config.options import HarmonicOptions

__all__ = ["DAMPING_RANGE_WHY", "DAMPING_WHY", "damping_range", "measured_damping",
           "state_damping"]

DAMPING_WHY = {  # why each damping model, for dynamic_stiffness.json
    "modal": ("constant modal damping ratio: the paper publishes no damping, so one ratio typical of bolted/"
              "guided machine structures is assumed for every mode; K_min = 2 zeta k_r then scales as the "
              "modal stiffness k_r, i.e. as (f_on/f_off)^2 for a mode whose modal mass at the drive point is "
              "unchanged"),
    "rayleigh": "Rayleigh damping C = alpha M + beta K with the configured coefficients",
    "joint": ("joint dashpots proportional to the joint springs (c = eta k_joint): zeta_r = eta w_r e_r / 2 with "
              "e_r the share of the mode's strain energy in the joints, so K_min scales as k_r w_r e_r — as "
              "(f_on/f_off)^3 only when e_r is about 1 in both states and the modal mass is unchanged"),
    "measured": "measured modal damping ratios of the dataset (mean measured ratio for unpaired modes)",
}
IDENTIFIED_WHY = ("joint damping identified from the measured modal damping ratios (identify stage): every mode's "
                  "ratio from its joint strain-energy shares per direction at the identified stiffness, ")

DAMPING_RANGE_WHY = ("harmonic.damping.damping_ratio_range, assumed (the paper publishes no damping): the modal "
                     "damping ratio of bolted, rolling-guide machine structures; every mode without a measured "
                     "ratio at one constant ratio over the range")
IDENTIFIED_RANGE_WHY = ("the identified damping's 95 % intervals: every mode at the lower, then at the upper end of "
                        "its ratio's interval (the law's covariance, inflated by the model error when the fit sits "
                        "above the noise)")


def measured_damping(folder: str, state: str, verify_csv) -> tuple[dict, str]:
    """Measured damping ratios by 0-based FE mode index (paired via verify.csv; ``folder``: the state's
    dataset), and a note."""
    from jointid.data.dataset import read_dataset

    if verify_csv is None:
        return {}, "no verify table: measured damping not used"
    try:
        ds = read_dataset(folder)
    except Exception as exc:  # the identify stage has validated the dataset already
        return {}, f"dataset {folder} not readable here ({str(exc).splitlines()[0]}): measured damping not used"
    zm = ds.damping(state) if state in ds.states else None
    if zm is None:
        return {}, f"dataset {folder} has no damping ratios for {state}"
    ver = io.read_csv(verify_csv)
    out = {}
    for order, fe_mode in zip(ver["order"], ver["fe_mode"]):
        if int(fe_mode) >= 1 and 1 <= int(order) <= len(zm):
            out[int(fe_mode) - 1] = float(zm[int(order) - 1])
    return out, f"measured damping ratios of {len(out)} paired modes from {folder}"


def state_damping(opts: HarmonicOptions, state: str, joint_damping: dict | None, model, modes, kc: dict, share, verify_csv) -> dict:
    """The damping ratio of every band mode of one state, and its source (module docstring).

    Parameters
    ----------
    opts : HarmonicOptions
        The harmonic stage's options (the configured damping, the model's joints, the state's dataset).
    state : str
    joint_damping : dict or None
        The identification's ``joint_damping`` record (:attr:`jointid.identification.record.IdentificationRecord.joint_damping`;
        None when the data carry no damping ratios).
    model, modes, kc
        The model, the band modes (``freqs_Hz``, ``phi``) and the state's stiffness coefficients.
    share : ndarray, shape (n_modes,)
        The modes' joint strain-energy share (all joints; 0 for rigid-body modes).
    verify_csv : str or None
        The verify table (pairs measured and FE modes for the measured ratios).

    Returns
    -------
    dict
        ``zeta`` ``(n_modes,)``, ``source`` (per mode), ``config`` (``harmonic.damping`` without the range),
        ``measured`` (a note), ``kind`` (:data:`~jointid.identification.damping_law.ASSUMED`, ``MEASURED`` or
        ``IDENTIFIED``), ``text`` (what Table 1 states), and with ``IDENTIFIED`` ``zeta_low, zeta_high`` and
        the ``law``.
    """
    dcfg = dict(opts.damping)  # the model's own fields; the range is Table 1's (damping_range)
    measured, mnote = measured_damping(opts.dataset, state, verify_csv)
    rec, note = usable_record(joint_damping)
    if rec is None:
        zeta, source = modal_damping_ratios(opts.damping_model, modes.freqs_Hz, joint_share=share,
                                            measured=measured)
        kind = MEASURED if MEASURED in source else ASSUMED
        return {"zeta": zeta, "source": source, "config": dcfg, "measured": mnote, "kind": kind,
                "text": (f"{kind}: harmonic.damping model {dcfg.get('model', 'modal')}"
                         + (", the measured ratios of the paired modes over it" if kind == MEASURED else "")
                         + ("" if joint_damping is None else f" ({note})"))}
    from jointid.synthetic.generate import joint_shares
    from jointid.fe.model import joint_terms

    fr = np.asarray(modes.freqs_Hz, float)
    el = fr >= RIGID_HZ
    spec = opts.model
    shares = joint_shares(model, modes.phi[:, el], fr[el], kc, joint_terms(spec.joints, spec.mesh_file),
                          rec["directions"])
    r = law_ratios(rec, shares, fr[el])
    out = {"source": np.where(el, IDENTIFIED, "rigid").tolist(), "config": dcfg, "measured": mnote,
           "kind": IDENTIFIED, "text": law_text(rec), "law": r["law"]}
    for key in ("zeta", "zeta_low", "zeta_high"):
        out[key] = np.zeros(fr.size)
        out[key][el] = r[key]
    return out


def damping_range(opts: HarmonicOptions, band: list[float], res, orders: dict, damping: dict) -> dict:
    """``dynamic_stiffness.json``'s ``damping_range``: the band minimum and the paired peaks under each pairing
    of ``orders`` (:func:`jointid.stages.harmonic.pairing_orders`), with its ``source``.

    Assumed or measured damping: over ``harmonic.damping.damping_ratio_range``
    (:func:`jointid.response.ranges.damping_ratio_range`), the measured ratios kept.  Identified damping
    (``damping`` of :func:`state_damping`): at the identified ratios' lower ends, values and upper ends
    (``damping_ratio_grid`` ``["low", "value", "high"]``; ``damping_ratio_low/high``: the governing mode's)."""
    paired = {n: o > 0 for n, o in orders.items()}
    if damping["kind"] != IDENTIFIED:
        rng = damping_ratio_range(
            band, res.freqs_Hz, res.zeta, res.participation, res.residual_flexibility_m_per_N or 0.0,
            opts.damping_ratio_range,
            fixed=np.asarray(res.damping_source) == "measured", paired=paired, n_freq=opts.n_freq)
        rng["source"] = DAMPING_RANGE_WHY
        return rng
    g = res.governing
    rng = {"damping_ratio_low": float(damping["zeta_low"][g]), "damping_ratio_high": float(damping["zeta_high"][g]),
           "damping_ratio_grid": ["low", "value", "high"]}
    rng.update(damping_vectors_range(band, res.freqs_Hz, [damping[k] for k in ("zeta_low", "zeta", "zeta_high")],
                                     res.participation, res.residual_flexibility_m_per_N or 0.0, paired=paired,
                                     n_freq=opts.n_freq))
    rng["source"] = IDENTIFIED_RANGE_WHY
    return rng


def why_text(damping: dict) -> str:
    """``dynamic_stiffness.json``'s ``damping.why``."""
    if damping["kind"] == IDENTIFIED:
        return IDENTIFIED_WHY + damping["text"]
    return DAMPING_WHY.get(damping["config"].get("model", "modal"), "")
