"""Discretisation check of identified joint parameters: how far would they move on a finer mesh?

The identified parameters carry the discretisation error of the FE model.  This module solves the
model once more at the identified parameters on a nested refinement of the mesh (chosen classes of
cells bisected, :func:`jointid.geometry.mesh.build_mesh`), pairs its modes with the default mesh's by MAC at the
measuring points and turns the frequency changes into the parameter change a re-identification on
the finer mesh would give, to first order (one Gauss-Newton step from the optimum):

    delta = -(J^T W J)^-1 J^T W (ln f_fine - ln f_default)

with ``J = d ln f / d log10 theta`` of the paired modes (exact modal sensitivities on the default
mesh) and ``W`` the identification weights.  Because the meshes are nested, the fine frequencies can
only be lower (min-max principle); the check reports both meshes' frequencies, the predicted
parameter change and the 95 % interval the measurement uncertainty alone gives, for comparison.

With ``mesh.extrapolate_edges`` the identification fits mesh-extrapolated frequencies
(:mod:`jointid.fe.extrapolate`).  With ``mesh_check.edge_levels`` the check compares like with like:
the extrapolated frequencies of the refined mesh (itself solved with one and two more edge levels)
against those of the default mesh.  Without it (the default: one solve) both meshes are compared at
their base level: the change of the base mesh's own frequencies under one halving, an estimate of the
error of the extrapolated frequencies, not a bound (on the paper's rig, 60 mm cells, thickness halved:
at most 0.22 / 0.27 % for the paired modes, against at most 0.21 % from the 40 mm family's
extrapolated limit, docs/reconstruction.md, "Mesh").

:func:`error_budget` holds each paired mode's estimated discretisation error against a fraction (one
third by default) of its frequency uncertainty, ``sqrt(s^2 + sigma_m^2)``: the stated measurement
noise ``s`` and the model error ``sigma_m`` of the identification (:mod:`jointid.identification.model_error`).
A mesh error well below that adds little to it: one third adds 5 % in quadrature.
"""

from __future__ import annotations

import numpy as np

from jointid.identification.record import IdentificationRecord


def error_budget(change_pct, par: IdentificationRecord, fraction: float, halved=None) -> dict:
    """Each paired mode's discretisation error against ``fraction`` of its frequency uncertainty.

    Parameters
    ----------
    change_pct : array_like, shape (n_measured,)
        Change of each measured mode's paired frequency on the refined mesh, in % (NaN: not paired
        or not followed).
    par : IdentificationRecord
        The identification: ``frequency_uncertainty_pct`` (the stated noise ``s``) and
        ``model_error.sigma_model_pct`` (``sigma_m``, 0 when absent).
    fraction : float
        ``mesh_check.budget_fraction``.
    halved : sequence of str, optional
        The cell classes the refined mesh halved (``mesh_check.halve``; None: every cell along all three
        axes).  Where they do not halve every
        cell along all three axes, the sentence says that a uniform refinement would find more: each
        halving lowers the frequencies, and to first order the three axes' shifts add up to the uniform
        refinement's (:mod:`jointid.diagnosis.mesh_error`).

    Returns
    -------
    dict
        ``uncertainty_pct`` (``sqrt(s^2 + sigma_m^2)``), ``budget_pct`` (``fraction`` of it),
        ``error_pct`` per measured mode (``|change|``), ``max_error_pct``, ``worst_mode`` (1-based),
        ``within`` (every followed mode within the budget) and ``sentence``.
    """
    err = np.abs(np.asarray(change_pct, float))
    s = float(par.frequency_uncertainty_pct or 0.0)
    sm = float((par.model_error or {}).get("sigma_model_pct") or 0.0)
    unc = float(np.hypot(s, sm))
    budget = fraction * unc
    ok = np.isfinite(err)
    worst = int(np.nanargmax(np.where(ok, err, -1.0))) if ok.any() else -1
    max_err = float(err[worst]) if worst >= 0 else float("nan")
    within = bool(ok.any() and max_err <= budget)
    from jointid.geometry.mesh import axes_halved

    part = "" if halved is None or all(axes_halved(tuple(halved))) else (
        f", with the {', '.join(halved)} cells halved: part of a uniform refinement's error, which is larger")
    sentence = (f"Mesh error at most {max_err:.2f} % (measured mode {worst + 1}{part}); the budget is "
                f"{budget:.2f} % ({fraction:.2g} x the frequency uncertainty {unc:.2f} % = sqrt(noise {s:.2g} %^2 "
                f"+ model error {sm:.2g} %^2)): " + ("within." if within else
                                                    "above it; refine the mesh (mesh.max_cell_size_m)."))
    return {"uncertainty_pct": unc, "noise_pct": s, "sigma_model_pct": sm, "fraction": float(fraction),
            "budget_pct": float(budget), "error_pct": [float(e) for e in err], "max_error_pct": max_err,
            "worst_mode": worst + 1, "within": within, "sentence": sentence}


def first_order_shift(J: np.ndarray, dlnf: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Parameter change (log10 units) of a least-squares fit when the model's ``ln f`` shift by ``dlnf``.

    ``J`` ``(n_modes, n_params)``: ``d ln f / d log10 theta``; the fit minimises
    ``sum w (ln f - ln f_meas)^2``; at its optimum a shift ``dlnf`` of the model moves it by
    ``-(J^T W J)^+ J^T W dlnf``.
    """
    J = np.asarray(J, float)
    w = np.ones(J.shape[0]) if weights is None else np.asarray(weights, float)
    A = J.T @ (w[:, None] * J)
    return -np.linalg.pinv(A) @ (J.T @ (w * np.asarray(dlnf, float)))


def parameter_changes(par: IdentificationRecord, delta: np.ndarray, limit_pct: float) -> tuple[dict, list[str]]:
    """Each identified parameter's first-order change on the refined mesh, and the warnings on them.

    Parameters
    ----------
    par : IdentificationRecord
        The identification (``parameters``: value and 95 % interval, N/m^3; ``on_bound``).
    delta : ndarray
        Change of each parameter in log10 units (:func:`first_order_shift`), in the order of
        ``par.names``.
    limit_pct : float
        ``mesh_check.max_parameter_change_pct``: a larger change (%) is warned about.

    Returns
    -------
    (params, warnings)
        ``params``: per parameter ``value, value_refined_first_order`` (N/m^3), ``change_pct``,
        ``ci95_half_width_pct`` (of its interval from the measurement uncertainty) and ``on_bound``.
    """
    params, warnings = {}, []
    for n, d in zip(par.names, delta):
        iv = par.interval(n)
        th = iv.value
        sigma_log10 = (np.log10(iv.ci95_high) - np.log10(iv.ci95_low)) / 2
        change = 100 * (10 ** d - 1)
        ci_half = 100 * (10 ** sigma_log10 - 1)
        on_bound = n in par.on_bound
        params[n] = {"value": float(th), "value_refined_first_order": float(th * 10 ** d),
                     "change_pct": float(change), "ci95_half_width_pct": float(ci_half), "on_bound": on_bound}
        if on_bound:
            warnings.append(f"{n} sits on a bound: the change is where it would move without the bound")
        if abs(change) > limit_pct:
            warnings.append(f"{n} would change by {change:+.1f} % on the refined mesh (more than "
                            f"mesh_check.max_parameter_change_pct = {limit_pct:g} %; its 95 % interval from the "
                            f"measurement uncertainty is +-{ci_half:.1f} %): the mesh is not converged for it")
    return params, warnings


def mode_table(f_default, f_refined, index, macs, fe_mode, raw: dict | None = None):
    """Every mode of the default mesh beside its partner on the refined mesh.

    ``f_default``/``f_refined``: the two meshes' frequencies (Hz; extrapolated ones with
    ``mesh.extrapolate_edges``, then ``raw`` holds the meshes' own as ``default_mesh_Hz`` and the
    refined mesh's array to be paired as ``refined_mesh_Hz``); ``index``/``macs``: the partner of each
    default mode (:func:`jointid.correlate.pairing.pair_by_shapes`, MAC >= 0.8); ``fe_mode``: the default-mesh mode (0-based, -1: none) of each
    measured mode.  Columns ``mode, default_Hz, refined_Hz, change_pct[, default_mesh_Hz,
    refined_mesh_Hz], mac, measured_mode`` (0: not paired with a measured mode).
    """
    import pandas as pd

    partner = lambda f: np.where(index >= 0, f[np.clip(index, 0, None)], np.nan)  # noqa: E731
    extra = {} if raw is None else {"default_mesh_Hz": raw["default_mesh_Hz"],
                                    "refined_mesh_Hz": partner(raw["refined_mesh_Hz"])}
    return pd.DataFrame({
        "mode": np.arange(1, len(f_default) + 1), "default_Hz": f_default, "refined_Hz": partner(f_refined),
        "change_pct": 100 * (partner(f_refined) / f_default - 1), **extra,
        "mac": macs,
        "measured_mode": [int(np.flatnonzero(fe_mode == j)[0]) + 1 if (fe_mode == j).any() else 0
                          for j in range(len(f_default))]})
