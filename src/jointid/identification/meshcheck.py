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
(:mod:`jointid.fe.extrapolate`), so the check compares like with like: the extrapolated frequencies of
the refined mesh (itself solved with one and two more edge levels) against those of the default mesh.
"""

from __future__ import annotations

import numpy as np

from jointid.errors import ModelError
from jointid.correlate.pairing import pair_by_shapes
from jointid.identification.updating import log_jacobian


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


def run_mesh_check(cfg: dict, state: str, params_json: str, verify_csv: str, matrices: str,
                   out_json: str, out_csv: str, log=print, edge_matrices: list[str] | None = None) -> dict:
    """Workflow stage: the mesh check of one state's identified parameters (see the module doc);
    ``edge_matrices``: the default mesh with one and two more edge levels (``mesh.extrapolate_edges``)."""
    import pandas as pd

    from jointid import io
    from functools import partial

    from jointid.fe.extrapolate import level_config
    from jointid.fe.model import build_model, joint_terms, load_model
    from jointid.stages.core import edge_limit_at, solve_point

    mc_cfg = cfg["mesh_check"]
    halve = tuple(mc_cfg["halve"])
    par = io.read_json(params_json)
    ver = pd.read_csv(verify_csv)
    names = list(par["parameters"])
    theta = np.array([par["parameters"][n]["value"] for n in names])
    theta_d = dict(zip(names, theta))
    def solve(model):
        _, shapes, _, modes = solve_point(cfg, model, theta_d, describe=False)
        return modes, shapes

    log(f"mesh_check[{state}]: default mesh at the identified parameters")
    coarse = load_model(matrices)
    modes_c, shapes_c = solve(coarse)
    jt = joint_terms(cfg["joints"])
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    J_all = log_jacobian(coarse.stiffness, modes_c.phi, modes_c.omega2, terms, theta)
    n_dofs_c = coarse.n_dofs
    f_c = modes_c.freqs_Hz
    say = lambda m: log(f"mesh_check[{state}]: {m}")  # noqa: E731
    if edge_matrices:
        say("default mesh: extrapolated over its edge levels")
        f_c = edge_limit_at(cfg, [coarse, *map(load_model, edge_matrices)], theta_d, log=say,
                            base=(modes_c.freqs_Hz, shapes_c)).limit_Hz
    del coarse
    say(f"the mesh with {', '.join(halve)} cells halved")
    if edge_matrices:  # and with one and two more edge levels, each built in turn
        lim_f = edge_limit_at(cfg, [partial(build_model, level_config(cfg, k), halve=halve, progress=say)
                                    for k in range(3)], theta_d, log=say)
        f_f, f_f_mesh, shapes_f, n_dofs_f = lim_f.limit_Hz, lim_f.levels_Hz[0], lim_f.shapes, lim_f.n_dofs[0]
    else:
        fine = build_model(cfg, halve=halve, progress=say)
        modes_f, shapes_f = solve(fine)
        f_f = f_f_mesh = modes_f.freqs_Hz
        n_dofs_f = fine.n_dofs
        del fine
    index, macs = pair_by_shapes(shapes_c, shapes_f, threshold=0.8)
    fe_mode = ver["fe_mode"].to_numpy(int) - 1  # paired default-mesh mode of each measured mode (-1: none)
    use = (fe_mode >= 0) & (index[np.clip(fe_mode, 0, None)] >= 0)
    if not use.any():
        raise ModelError(f"mesh_check[{state}]: no measured mode could be followed onto the refined mesh "
                         "(MAC < 0.8 at the measuring points for every paired mode) — check the mesh settings")
    rows = fe_mode[use]
    dlnf = np.log(f_f[index[rows]] / f_c[rows])
    weights = np.asarray(cfg["identify"].get("weights") or np.ones(len(fe_mode)), float)[use]
    delta = first_order_shift(J_all[rows], dlnf, weights)
    sigma_log10 = {n: (np.log10(par["parameters"][n]["ci95_high"]) - np.log10(par["parameters"][n]["ci95_low"])) / 2
                   for n in names}
    limit = float(mc_cfg["max_parameter_change_pct"])
    params = {}
    warnings = []
    lost = [i + 1 for i in np.flatnonzero((fe_mode >= 0) & ~use)]
    if lost:
        warnings.append(f"measured mode(s) {', '.join(map(str, lost))}: the paired mode has no partner with "
                        "MAC >= 0.8 on the refined mesh; left out of the estimate")
    for n, th, d in zip(names, theta, delta):
        change = 100 * (10 ** d - 1)
        ci_half = 100 * (10 ** sigma_log10[n] - 1)
        on_bound = n in par.get("on_bound", [])
        params[n] = {"value": float(th), "value_refined_first_order": float(th * 10 ** d),
                     "change_pct": float(change), "ci95_half_width_pct": float(ci_half), "on_bound": on_bound}
        if on_bound:
            warnings.append(f"{n} sits on a bound: the change is where it would move without the bound")
        if abs(change) > limit:
            warnings.append(f"{n} would change by {change:+.1f} % on the refined mesh (more than "
                            f"mesh_check.max_parameter_change_pct = {limit:g} %; its 95 % interval from the "
                            f"measurement uncertainty is +-{ci_half:.1f} %): the mesh is not converged for it")
    partner = lambda f: np.where(index >= 0, f[np.clip(index, 0, None)], np.nan)  # noqa: E731
    raw = {} if not edge_matrices else {  # the meshes' own frequencies beside the extrapolated ones
        "default_mesh_Hz": modes_c.freqs_Hz, "refined_mesh_Hz": partner(f_f_mesh)}
    table = pd.DataFrame({
        "mode": np.arange(1, len(f_c) + 1), "default_Hz": f_c, "refined_Hz": partner(f_f),
        "change_pct": 100 * (partner(f_f) / f_c - 1), **raw,
        "mac": macs,
        "measured_mode": [int(np.flatnonzero(fe_mode == j)[0]) + 1 if (fe_mode == j).any() else 0
                          for j in range(len(f_c))]})
    io.write_csv(table, out_csv)
    doc = {"state": state, "halved": list(halve), "extrapolated_over_edge_levels": bool(edge_matrices),
           "n_dofs_default": int(n_dofs_c), "n_dofs_refined": int(n_dofs_f),
           "parameters": params, "max_parameter_change_pct": limit, "warnings": warnings,
           "max_paired_frequency_change_pct": float(100 * np.max(np.abs(np.expm1(dlnf))))}
    io.write_json(out_json, doc)
    for n, p in params.items():
        log(f"mesh_check[{state}]: {n} {p['value']:.4g} -> {p['value_refined_first_order']:.4g} N/m^3 "
            f"({p['change_pct']:+.2f} %; 95 % interval +-{p['ci95_half_width_pct']:.1f} %)")
    for w in warnings:
        log(f"mesh_check[{state}]: WARNING {w}")
    return doc
