"""What the data cannot decide: absorbed effects, indistinguishable candidates, the measurement that would
decide (docs/effects.md, "When the data cannot decide").

* :func:`absorption` — a candidate that the fitted parameters can imitate: at the size that moves the
  most sensitive measured mode by ``shift_pct``, the fitted parameters take up all but a chi-square
  of 3.84 of it, so the data cannot tell it from them; the bias it would cause in each parameter
  is the least-squares shift ``J_x^+ J_t t``.
* :func:`tie_groups` — candidates that explain the data within ``tie_delta_aicc`` of each other.
* :func:`next_measurements` — for an indistinguishable set, the measurements whose predictions differ
  most between the candidates' refits, relative to the noise (expected chi-square difference): a
  further mode (a model mode not measured today), another force level, or, for a state measured
  without shapes, an accelerometer pair whose mode shapes would decide (:mod:`jointid.diagnosis.shape_proposal`;
  the fits use shapes where they are measured, :mod:`jointid.diagnosis.shape_residuals`).
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from jointid.correlate.pairing import pair_by_shapes
from jointid.diagnosis.judging import supported
from jointid.diagnosis.results import frequency_rows, row_sigma, whitener
from jointid.diagnosis.shape_proposal import accelerometer_rows
from jointid.diagnosis.terms import StateInfo
from jointid.identification.model_error import NO_MODEL_ERROR, ModelError

if TYPE_CHECKING:
    from jointid.diagnosis.fitting import Diagnoser
    from jointid.diagnosis.results import Fit

__all__ = ["CHI2_1_95", "absorption", "absorption_notes", "explain_tie", "tie_groups", "next_measurements",
           "prediction_spread"]

CHI2_1_95 = 3.841  # chi-square quantile, 1 degree of freedom, 95 %: a difference the data could show


def absorption(current, Jt: np.ndarray, data, shift_pct: float, me: ModelError = NO_MODEL_ERROR) -> dict:
    """How far the fitted parameters of ``current`` can imitate a candidate with Jacobian ``Jt`` (n, 1).

    Chi-squares are at the total uncertainty of ``me`` (the stated noise plus the model error): a
    change the model error could hide is no change the data could show.

    Returns ``absorbed`` (bool: the candidate at the tested size leaves less than a chi-square of
    3.84 once the parameters are refitted, while it moves the data by far more), ``size_t`` (the test
    variable at the tested size), ``chi2_raw`` (what the candidate changes, in chi-square), ``chi2_left``
    (what the refitted parameters cannot take up) and ``bias_pct`` (label -> parameter shift, %;
    joint stiffnesses are logarithmic, so ``100 (exp(dx) - 1)``).
    """
    ev = current.ev
    jt = np.asarray(Jt, float)[:, 0]
    f = frequency_rows(ev)
    jf = jt[f] if not f.all() else jt
    s = row_sigma(ev, data)
    peak = float(np.max(np.abs(jf * s))) if jf.size else 0.0
    if peak <= 0 or ev.J.shape[1] == 0:
        return {"absorbed": False, "size_t": 0.0, "chi2_raw": 0.0, "chi2_left": 0.0, "bias_pct": {}}
    t = shift_pct / 100.0 / peak
    A = whitener(ev, data, me)  # rows in units of the total uncertainty (the identity without a model error)
    d = A @ (jt * t)
    Jw = A @ ev.J
    dx, *_ = np.linalg.lstsq(Jw, d, rcond=None)
    left = d - Jw @ dx
    var = current.variant
    bias = {}
    for j, lab in enumerate(var.labels):
        bias[lab] = float(100 * np.expm1(dx[j])) if j < var.p else float(dx[j])
    chi2_raw, chi2_left = float(d @ d), float(left @ left)
    return {"absorbed": bool(chi2_left < CHI2_1_95 <= chi2_raw), "size_t": float(t), "chi2_raw": chi2_raw,
            "chi2_left": chi2_left, "bias_pct": bias}


def absorption_text(effect: str, value: float, unit: str, pname: str, info: dict, shift_pct: float,
                    n_joint: int) -> str:
    """The sentence on an absorbed candidate: what it is confused with and the bias it would cause."""
    joint = dict(list(info["bias_pct"].items())[:n_joint])
    worst = sorted(joint.items(), key=lambda kv: -abs(kv[1]))
    parts = ", ".join(f"{k} by {v:+.0f} %" for k, v in worst if abs(v) >= 0.5) or "nothing measurable"
    return (f"the data cannot tell {effect} from a change of the joint parameters: at {pname} = {value:.3g} "
            f"{unit} (a size that moves the most sensitive mode by {shift_pct:g} %, chi-square "
            f"{info['chi2_raw']:.0f}) the refitted joints take up all but {info['chi2_left']:.1f} of it; "
            f"if it is present, they are biased: {parts}")


def leading(ranking: pd.DataFrame) -> np.ndarray:
    """Which ranking rows lead: those that explain the data at the noise, or, when none does, those
    the data support against the current model (:func:`jointid.diagnosis.judging.supported`)."""
    ok = ranking["explains"].astype(bool).to_numpy()
    if ok.any() or "support" not in ranking:
        return ok
    return supported(ranking)


def tie_groups(ranking: pd.DataFrame, tie_delta_aicc: float) -> list[str]:
    """Per ranking row, the other candidates indistinguishable from it (";"-joined, "" for none):
    both lead (:func:`leading`) and their QAICc differ by less than ``tie_delta_aicc`` (or cannot be
    compared: QAICc is infinite when there are no more residuals than parameters + 1).  QAICc is
    AICc where the best model fits within its noise."""
    out = []
    ok = leading(ranking)
    a = ranking["delta_qaicc" if "delta_qaicc" in ranking else "delta_aicc"].to_numpy(float)
    names = ranking["effect"].astype(str).to_numpy()
    for i in range(len(ranking)):
        if not ok[i]:
            out.append("")
            continue
        # a non-finite AICc (no more residuals than parameters + 1) cannot separate anything
        out.append(";".join(names[j] for j in range(len(ranking)) if j != i and ok[j]
                            and (not np.isfinite(a[j] - a[i]) or abs(a[j] - a[i]) < tie_delta_aicc)))
    return out


def _match(sa, sb) -> np.ndarray:
    """Mode of solution ``sb`` matching each mode of ``sa`` by MAC of the probe shapes (-1 below 0.5)."""
    return pair_by_shapes(np.asarray(sa.shapes, float), np.asarray(sb.shapes, float), threshold=0.5)[0]


def _further_modes(diag, fits: dict, names: list[str]) -> list[dict]:
    """Model modes not measured today, each state: the candidates' predicted frequencies."""
    rows = []
    base = fits[names[0]]
    for si, d in enumerate(diag.data):
        sa = base.ev.solutions[si]
        taken = set(np.asarray(base.ev.index[si])[np.asarray(base.ev.index[si]) >= 0].tolist())
        others = [(n, fits[n].ev.solutions[si], _match(sa, fits[n].ev.solutions[si])) for n in names[1:]]
        for j in range(len(sa.freqs_Hz)):
            if j in taken or sa.freqs_Hz[j] < diag.min_freq:
                continue
            f = {names[0]: float(sa.freqs_Hz[j])}
            for n, sb, m in others:
                if m[j] >= 0:
                    f[n] = float(sb.freqs_Hz[m[j]])
            if len(f) < len(names):
                continue
            rows.append({"measurement": f"{d.name}: the mode near {sa.freqs_Hz[j]:.0f} Hz, not measured today "
                                        "(extend the measured band to it)",
                         "kind": "further mode", "state": d.name, "em_force_N": d.info.em_force_N,
                         "predictions_Hz": f, "sigma_rel": d.noise_rms()})
    return rows


def _force_levels(diag, fits: dict, names: list[str]) -> list[dict]:
    """The measured modes at force levels not tested: halfway between the tested ones and 1.5 times
    the largest (each candidate's refit solved there)."""
    forces = sorted({float(d.info.em_force_N) for d in diag.data})
    new = [0.5 * (a + b) for a, b in zip(forces, forces[1:])] + ([1.5 * forces[-1]] if forces[-1] > 0 else [])
    ref = max(diag.data, key=lambda d: len(d.f_meas))
    si = diag.data.index(ref)
    rows = []
    for F in new:
        info = StateInfo(f"em_force_{F:g}N", F)
        sols = {n: diag.solver.solve(*fits[n].variant.coefficients(fits[n].x, info), diag.n_modes)
                for n in names}
        idx = np.asarray(fits[names[0]].ev.index[si])
        sa = sols[names[0]]
        ref_sol = fits[names[0]].ev.solutions[si]
        to_new = _match(ref_sol, sa)  # measured-state modes continued to the new force level
        maps = {n: _match(sa, sols[n]) for n in names[1:]}
        for i in np.flatnonzero(idx >= 0):
            j = to_new[idx[i]]
            if j < 0:
                continue
            f = {names[0]: float(sa.freqs_Hz[j])}
            for n in names[1:]:
                if maps[n][j] >= 0:
                    f[n] = float(sols[n].freqs_Hz[maps[n][j]])
            if len(f) == len(names):
                rows.append({"measurement": f"a state at em_force_N = {F:g} N: mode {i + 1} (as measured in "
                                            f"{ref.name}, near {sa.freqs_Hz[j]:.0f} Hz)",
                             "kind": "force level", "state": info.name, "em_force_N": F,
                             "predictions_Hz": f, "sigma_rel": ref.noise_rms(), "group": f"force {F:g}"})
    return rows


def prediction_spread(f: dict, sigma_rel: float) -> float:
    """Smallest expected chi-square difference between any two candidates' predictions of one
    measured frequency: ``min over pairs (ln(f_a / f_b) / sigma)^2``."""
    vals = list(f.values())
    return min((np.log(a / b) / sigma_rel) ** 2 for a, b in itertools.combinations(vals, 2))


def next_measurements(diag, fits: dict, names: list[str], top: int = 3,
                      me: ModelError = NO_MODEL_ERROR) -> pd.DataFrame:
    """The measurements that would best separate the candidates ``names`` (their refits in ``fits``).

    Each row: ``measurement`` (what to measure), ``kind`` (further mode, force level), ``state``,
    ``em_force_N``, ``expected_delta_chi2`` (the smallest, over candidate pairs, squared difference of
    their predictions in noise units), ``predictions`` (candidate: Hz, or displacement ratios of a shape
    row).  A force level is one new
    state: its row sums the expected difference over the modes measured today.  The difference is in
    units of the total uncertainty of ``me`` (the model error blurs a new measurement as it does the
    old ones).  Sorted best first, ``top`` rows, plus the best accelerometer position (kind ``shape``)
    when none of them is one.
    """
    rows = _further_modes(diag, fits, names)
    forces = _force_levels(diag, fits, names)
    for r in rows + forces:
        r["sigma_rel"] = float(np.hypot(r["sigma_rel"], me.sigma_model_rel))
    by_force = {}
    for r in forces:
        g = by_force.setdefault(r["group"], {**r, "expected_delta_chi2": 0.0, "parts": []})
        g["expected_delta_chi2"] += prediction_spread(r["predictions_Hz"], r["sigma_rel"])
        g["parts"].append(r["predictions_Hz"])
    out = []
    for r in rows:
        out.append({"measurement": r["measurement"], "kind": r["kind"], "state": r["state"],
                    "em_force_N": r["em_force_N"],
                    "expected_delta_chi2": prediction_spread(r["predictions_Hz"], r["sigma_rel"]),
                    "predictions": "; ".join(f"{n} {v:.1f} Hz" for n, v in r["predictions_Hz"].items())})
    for g in by_force.values():
        out.append({"measurement": f"a state at em_force_N = {g['em_force_N']:g} N (the modes measured today)",
                    "kind": "force level", "state": g["state"], "em_force_N": g["em_force_N"],
                    "expected_delta_chi2": g["expected_delta_chi2"],
                    "predictions": "; ".join(f"{n} {np.mean([p[n] for p in g['parts']]):.1f} Hz (mean)"
                                             for n in names)})
    out += accelerometer_rows(diag, fits, names)  # states measured without shapes (jointid.diagnosis.shape_proposal)
    cols = ["measurement", "kind", "state", "em_force_N", "expected_delta_chi2", "predictions"]
    df = pd.DataFrame(out, columns=cols).sort_values("expected_delta_chi2", ascending=False, kind="stable")
    best = df.head(top)
    shape = df[df["kind"] == "shape"].head(1)  # the accelerometer position is always among the proposals
    if len(shape) and not (best["kind"] == "shape").any():
        best = pd.concat([best, shape])
    return best.reset_index(drop=True)


def absorption_notes(diag: Diagnoser, current: Fit, rows: list, ranking: pd.DataFrame,
                     shift_pct: float, me: ModelError = NO_MODEL_ERROR) -> list[str]:
    """Step 6: the candidates the fitted parameters could be hiding (:func:`absorption`);
    fills the ranking's ``absorbed`` and ``absorbed_bias_pct`` columns and returns one sentence each."""
    out = []
    ranking["absorbed"] = False
    ranking["absorbed_bias_pct"] = np.nan
    for row, spec, st in rows:
        if spec is None or st is None:
            continue
        info = absorption(current, st["Jt"], diag.data, shift_pct, me)
        if not info["absorbed"]:
            continue
        p0 = spec.effect.params[0]
        at = ranking.index[ranking["effect"] == row["effect"]]
        joint = [v for k, v in info["bias_pct"].items() if k in current.variant.joint_names]
        ranking.loc[at, "absorbed"] = True
        ranking.loc[at, "absorbed_bias_pct"] = max(joint, key=abs) if joint else np.nan
        out.append(absorption_text(row["effect"], p0.from_t(info["size_t"]), p0.unit, p0.name, info,
                                             shift_pct, current.variant.p))
    return out


def explain_tie(diag: Diagnoser, ranking: pd.DataFrame, fits: dict,
                me: ModelError = NO_MODEL_ERROR) -> tuple[str, pd.DataFrame]:
    """Step 7 of the loop: for leading candidates (:func:`leading`) the data cannot tell apart, how far their
    refits differ and the measurements that would decide (:func:`ambiguity.next_measurements`); ("", empty)
    otherwise."""
    explaining = ranking[leading(ranking)]
    if not len(explaining) or not explaining.iloc[0]["indistinguishable_from"]:
        return "", pd.DataFrame()
    names = [str(explaining.iloc[0]["effect"])] + str(explaining.iloc[0]["indistinguishable_from"]).split(";")
    tied = {n: fits["+" + n] for n in names}
    joints = tied[names[0]].variant.joint_names
    spread = []
    for j, lab in enumerate(joints):
        v = [math.exp(float(f.x[j])) for f in tied.values()]
        spread.append(f"{lab} {min(v):.3g} .. {max(v):.3g} ({100 * (max(v) / min(v) - 1):.0f} %)")
    dmax = 0.0
    for si, d in enumerate(diag.data):
        fm = np.array([f.ev.f_model[si] for f in tied.values()])
        with np.errstate(invalid="ignore"):
            dmax = max(dmax, float(np.nanmax(np.abs(np.log(fm.max(0) / fm.min(0)))) * 100) if fm.size else 0.0)
    detail = (f"Their refitted joint parameters differ ({'; '.join(spread)}) and their predictions of the "
              f"measured modes by at most {dmax:.2f} %.")
    return detail, next_measurements(diag, {n: tied[n] for n in names}, names, me=me)
