"""Test statistics of the diagnosis: score tests, between-state contrasts, identifiability, AICc.

See docs/effects.md.  Residuals are sigma-normalised (``r_i = ln(f_model / f_meas) / sigma``), so the
chi-square of a fit is ``r^T r`` and sigma is known:

* score (Lagrange-multiplier) test of a candidate with parameters t at t = 0 (effect absent):
  ``P = I - J_x J_x^+``, ``LM = r^T P J_t (J_t^T P J_t)^+ J_t^T P r`` ~ chi2(q); one-sided for a
  parameter whose null sits on its bound (mass >= 0, compliance >= 0, beta >= 0): p = 0.5 chi2_1 sf,
  and a linearised estimate of the wrong sign explains nothing.  Explained fraction ``LM / r^T r``;
* AICc and the chi-square p-value are in :mod:`jointid.diagnosis.criteria` (numbers only, below
  the fits that use them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from jointid.diagnosis.criteria import chi2_sf
from jointid.fe.reduced import Solution

if TYPE_CHECKING:
    from jointid.diagnosis.fitting import Diagnoser, Evaluation, Fit
    from jointid.diagnosis.variants import EffectSpec, Variant

# a Jacobian column that a projection shrinks below this fraction of its norm is round-off (the
# reduced solver's eigenvalues are accurate to 1e-6; a real between-state sensitivity is O(1))
NEGLIGIBLE = 1e-4


def extra_jacobian(diag: Diagnoser, variant: Variant, x, ev: Evaluation, cols) -> np.ndarray:
    """Jacobian columns ``cols`` of ``variant`` at ``x`` using the solutions and pairing of ``ev``."""
    out = []
    for si, (d, sol) in enumerate(zip(diag.data, ev.solutions)):
        idx = np.asarray(ev.index[si])
        ok = np.flatnonzero(idx >= 0)
        mis = ev.misfits[si][0] if ev.misfits else np.zeros(0, int)
        use = np.concatenate([idx[ok], mis]).astype(int)
        sub = Solution(sol.freqs_Hz[use], sol.lam[use], sol.Y[:, use], sol.lam_all, sol.Y_all,
                       sol.kc, sol.mc, sol.shapes[:, use], sol.generation)
        at = np.concatenate([np.arange(len(ok)), len(idx) + np.arange(len(mis))]).astype(int)
        dc = variant.dcoefficients(x, d.info)
        Jb = np.zeros((len(idx) + len(mis), len(cols)))
        for k, dlam in enumerate(diag.solver.sensitivities(sub, [dc[j] for j in cols])):
            Jb[at, k] = dlam / (2 * np.maximum(sub.lam, 1e-9))
        out.append(Jb)
    n_f = sum(len(b) for b in out)
    out = [np.vstack(out) / np.asarray(ev.sigma, float)[:n_f, None]] if out else out
    if diag.shapes.active:  # the shape rows follow every frequency row (jointid.diagnosis.shape_residuals)
        dirs = [[dc[j] for j in cols] for dc in (variant.dcoefficients(x, d.info) for d in diag.data)]
        out.append(diag.shapes.block(diag.solver, ev.solutions, ev.index, dirs).arrays()[1])
    return np.vstack(out)


def score_test(r: np.ndarray, Jx: np.ndarray, Jt: np.ndarray, t_lower: np.ndarray, *,
               scale_x: np.ndarray | None = None, scale_t: np.ndarray | None = None) -> dict:
    """Lagrange-multiplier (score) test of extra parameters ``t`` at ``t = 0``.

    Parameters
    ----------
    r : (n,) sigma-normalised residuals of the fitted (restricted) model.
    Jx : (n, p) Jacobian of the fitted parameters.
    Jt : (n, q) Jacobian of the candidate's parameters at their null.
    t_lower : (q,) lower bounds of ``t`` (0 when the null is on the bound).
    scale_x, scale_t : (p,), (q,) optional
        Column norms of the Jacobians before a projection (e.g. onto between-state contrasts).  A
        column that the projection shrinks below ``NEGLIGIBLE`` of its norm is round-off (a
        parameter acting alike in every state has no between-state sensitivity) and is dropped:
        its direction would otherwise be arbitrary.

    Returns
    -------
    dict
        ``score`` (LM statistic), ``p_value``, ``explained_fraction``, ``t_hat`` (linearised estimate),
        ``sign_ok``, ``collinearity`` (norm of the projected over the raw sensitivity, 0 = fully
        explained by the fitted parameters).
    """
    n, q = Jt.shape
    if scale_x is not None:
        Jx = Jx[:, np.linalg.norm(Jx, axis=0) > NEGLIGIBLE * np.asarray(scale_x)]
    if scale_t is not None:
        Jt = np.where(np.linalg.norm(Jt, axis=0) > NEGLIGIBLE * np.asarray(scale_t), Jt, 0.0)
    if Jx.shape[1]:
        U, sv, _ = np.linalg.svd(Jx, full_matrices=False)
        Q = U[:, sv > 1e-10 * sv.max()] if sv.max() > 0 else U[:, :0]  # range of Jx (rank-revealing)
        PJ = Jt - Q @ (Q.T @ Jt)
    else:
        PJ = Jt
    raw = np.linalg.norm(Jt, axis=0)
    proj = np.linalg.norm(PJ, axis=0)
    coll = float(np.min(np.where(raw > 0, proj / np.where(raw > 0, raw, 1), 0.0))) if q else 0.0
    g = PJ.T @ r
    H = PJ.T @ PJ
    Hinv = np.linalg.pinv(H, rcond=1e-10)
    lm = float(g @ Hinv @ g)
    t_hat = -Hinv @ g
    rr = float(r @ r)
    sign_ok = bool(np.all(t_hat >= t_lower - 1e-12))
    if raw.max() == 0 or coll < 1e-6:
        lm = 0.0
    if q == 1 and t_lower[0] == 0.0:
        p = 0.5 * chi2_sf(lm, 1) if sign_ok else 1.0
    else:
        p = chi2_sf(lm, q)
    explained = (lm / rr if rr > 0 else 0.0) if sign_ok else 0.0
    return {"score": lm if sign_ok else 0.0, "score_two_sided": lm, "p_value": p if lm > 0 else 1.0,
            "explained_fraction": float(min(explained, 1.0)), "t_hat": t_hat, "sign_ok": sign_ok,
            "collinearity": coll}


def score_candidate(diag: Diagnoser, current: Fit, spec: EffectSpec, C: np.ndarray, row: dict) -> dict:
    """Score tests of one applicable candidate; fills ``row`` and returns the all-states test."""
    ev = current.ev
    var = current.variant.extended(spec)
    x_ext = np.concatenate([current.x, np.zeros(var.n_params - current.variant.n_params)])
    cols = list(range(current.variant.n_params, var.n_params))
    Jt = extra_jacobian(diag, var, x_ext, ev, cols)
    lower = np.array([var.lower[c] for c in cols])
    st = score_test(ev.r, ev.J, Jt, lower)
    st["Jt"] = Jt
    p0 = spec.effect.params[0]
    row.update({"explained_fraction": st["explained_fraction"], "score": st["score"],
                "p_value": st["p_value"], "linear_estimate": p0.from_t(float(st["t_hat"][0])),
                "collinearity": st["collinearity"], "note": ""})
    if len(C):
        sd = score_test(C @ ev.r, C @ ev.J, C @ Jt, lower, scale_x=np.linalg.norm(ev.J, axis=0),
                        scale_t=np.linalg.norm(Jt, axis=0))
        row.update({"between_states_fraction": sd["explained_fraction"],
                    "between_states_p_value": sd["p_value"]})
    if st["collinearity"] < 1e-3:
        row["note"] = "collinear with the fitted parameters (cannot be told apart from them)"
    elif not st["sign_ok"]:
        row["note"] = "would need a value outside its physical range (wrong sign)"
    return st


def state_contrasts(ev: Evaluation, n_states: int) -> np.ndarray:
    """Orthonormal between-state contrasts ``C`` of the residual vector ``(n_c, n)``.

    For every measured mode number paired in all states, the residuals across the states are
    projected onto the complement of the all-ones vector (Helmert basis), so ``C r`` is the part of
    the residual that differs between states (unit variance per component, like ``r``).  Effects
    acting alike in every state (masses, supports) have no sensitivity there; only state-dependent
    effects can explain it.
    """
    if n_states < 2:
        return np.zeros((0, len(ev.r)))
    paired = {}
    for k, (si, mode) in enumerate(ev.rows):
        if mode >= 1 and ev.index[si][mode - 1] >= 0:  # mode 0: a misfit row
            paired.setdefault(mode, {})[si] = k
    H = np.zeros((n_states - 1, n_states))
    for j in range(1, n_states):
        H[j - 1, :j] = 1.0
        H[j - 1, j] = -j
        H[j - 1] /= np.linalg.norm(H[j - 1])
    rows = []
    for mode, by_state in sorted(paired.items()):
        if len(by_state) != n_states:
            continue
        for h in H:
            c = np.zeros(len(ev.r))
            for si, k in by_state.items():
                c[k] = h[si]
            rows.append(c)
    return np.array(rows) if rows else np.zeros((0, len(ev.r)))


def identifiability(J: np.ndarray, labels: list[str], threshold: float = 1e-3) -> dict:
    """SVD of the column-normalised Jacobian: condition and the weakest parameter combination."""
    if J.size == 0:
        return {"ratio": 1.0, "weak": "", "flag": False}
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    s, V = np.linalg.svd(Jn, full_matrices=False)[1:]
    ratio = float(s[-1] / s[0]) if s[0] > 0 else 0.0
    v = V[-1]
    parts = [f"{c:+.2f} {lab}" for c, lab in sorted(zip(v, labels), key=lambda t: -abs(t[0])) if abs(c) > 0.1]
    return {"ratio": ratio, "weak": " ".join(parts), "flag": bool(ratio < threshold or np.any(norms == 0))}
