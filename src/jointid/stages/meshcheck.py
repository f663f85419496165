"""Rule ``mesh_check`` (``mesh_check.enabled``, on by default): each state's identified parameters re-solved
on a nested refinement of the mesh, and the first-order change a re-identification there would give
(:mod:`jointid.identification.meshcheck`).  The default mesh's solve at those parameters is rule verify's
(``optimum_modes.npz``), unless both meshes are extrapolated over their edge levels.

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`).
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from jointid import io
from jointid.errors import ModelError

if TYPE_CHECKING:
    from jointid.config.options import MeshCheckOptions



def _default_mesh(spec, theta_d, names, theta, matrices, edge_models, say):
    """Solve of the default mesh at the identified parameters (``spec``: the model's
    :class:`~jointid.config.typed.ModelSpec`).

    Returns ``(frequencies (Hz; extrapolated over ``edge_models``: the mesh with one and two more
    edge levels, or functions that build them), its own frequencies, shapes,
    d ln f / d log10 theta of every mode, number of DOFs)``.
    """
    from jointid.fe.model import load_model
    from jointid.identification.optimum_modes import optimum_modes
    from jointid.identification.polish import edge_limit_at, solve_point

    coarse = load_model(matrices)
    _, shapes_c, _, modes_c = solve_point(spec, coarse, theta_d, describe=False)
    J_all = optimum_modes(spec, coarse, names, theta, modes_c.freqs_Hz, shapes_c, modes_c.phi,
                          modes_c.omega2).dlnf_dlog10theta
    f_c = modes_c.freqs_Hz
    if edge_models:
        say("default mesh: extrapolated over its edge levels")
        f_c = edge_limit_at(spec, [coarse, *edge_models], theta_d, log=say,
                            base=(modes_c.freqs_Hz, shapes_c)).limit_Hz
    return f_c, modes_c.freqs_Hz, shapes_c, J_all, coarse.n_dofs


def _refined_mesh(spec, theta_d, halve, extrapolate: bool, say, fine=None):
    """Solve of the mesh with the ``halve`` cells halved (and its edge levels with
    ``extrapolate``); returns ``(frequencies, its own frequencies, shapes, number of DOFs)``.  ``fine``: that
    mesh's model, built before (:func:`run_mesh_checks`: one build for every state)."""
    from jointid.fe.model import build_model
    from jointid.fe.modal import SURVEY_TOL
    from jointid.identification.polish import edge_limit_at, solve_point

    if extrapolate:  # and with the edge levels the extrapolation solves, each built in turn
        lim_f = edge_limit_at(spec, [partial(build_model, spec.with_edge_levels(k), halve=halve, progress=say)
                                    for k in (0, *spec.mesh.edge_extra_levels)], theta_d, log=say)
        return lim_f.limit_Hz, lim_f.levels_Hz[0], lim_f.shapes, lim_f.n_dofs[0]
    fine = fine if fine is not None else build_model(spec, halve=halve, progress=say)
    _, shapes_f, _, modes_f = solve_point(spec, fine, theta_d, describe=False, tol=SURVEY_TOL)
    return modes_f.freqs_Hz, modes_f.freqs_Hz, shapes_f, fine.n_dofs


def run_mesh_checks(opts: MeshCheckOptions, states: list[str], params_jsons: list[str], verify_csvs: list[str],
                    matrices: str, out_jsons: list[str], out_csvs: list[str], log=print,
                    modes_npzs: list[str] | None = None) -> list[dict]:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rule ``mesh_check``: :func:`run_mesh_check` of every state of ``states`` (the lists aligned with it) in
    one process.  The refined mesh is the same for every state: it is built once (without the edge
    levels; with them each state builds its levels in turn, as they are dropped after each solve)."""
    from jointid.fe.model import build_model

    fine = None
    if not opts.extrapolate:
        log(f"mesh_check: the mesh with {', '.join(opts.halve)} cells halved, built once for "
            f"{len(states)} state(s)")
        fine = build_model(opts.model, halve=opts.halve, progress=lambda m: log(f"mesh_check: {m}"))
    modes = modes_npzs or [None] * len(states)
    return [run_mesh_check(opts, s, p, v, matrices, j, c, log=log, modes_npz=m, fine=fine)
            for s, p, v, j, c, m in zip(states, params_jsons, verify_csvs, out_jsons, out_csvs, modes)]


def run_mesh_check(opts: MeshCheckOptions, state: str, params_json: str, verify_csv: str, matrices: str,
                   out_json: str, out_csv: str, log=print, modes_npz: str | None = None, fine=None) -> dict:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rule ``mesh_check`` for one state's identified parameters (see the module doc); with
    ``mesh_check.edge_levels`` and ``mesh.extrapolate_edges`` both meshes are extrapolated over one and
    two more edge levels (built in this job).  ``modes_npz``: rule verify's solve of the default mesh at the
    identified parameters (:class:`jointid.identification.optimum_modes.OptimumModes`), used instead of
    solving it again when the meshes are compared at their base level.

    Writes every mode of the default mesh beside the refined mesh's (``out_csv``,
    :func:`jointid.identification.meshcheck.mode_table`) and the parameters' first-order change
    (``out_json``); returns the latter.
    """
    import pandas as pd

    from jointid.correlate.pairing import pair_by_shapes
    from jointid.fe.model import edge_level_builders
    from jointid.identification.meshcheck import error_budget, first_order_shift, mode_table, parameter_changes
    from jointid.identification.optimum_modes import OptimumModes
    from jointid.identification.record import IdentificationRecord

    halve = opts.halve
    par = IdentificationRecord.read(params_json)
    ver = io.read_csv(verify_csv)
    names = par.names
    theta = np.array(list(par.theta.values()))
    theta_d = dict(zip(names, theta))
    say = lambda m: log(f"mesh_check[{state}]: {m}")  # noqa: E731
    # mesh_check.edge_levels: both meshes extrapolated over their edge levels; else both at their base level
    spec = opts.model
    edges = opts.extrapolate
    if modes_npz and not edges:
        at = OptimumModes.read(modes_npz)
        at.check_parameters(names, [par.theta[n] for n in names], modes_npz)
        say("default mesh at the identified parameters: rule verify's solve")
        f_c = f_c_mesh = at.freqs_Hz
        shapes_c, J_all, n_dofs_c = at.shapes, at.dlnf_dlog10theta, at.n_dofs
    else:
        say("default mesh at the identified parameters")
        f_c, f_c_mesh, shapes_c, J_all, n_dofs_c = _default_mesh(
            spec, theta_d, names, theta, matrices, edge_level_builders(spec, progress=say) if edges else [], say)
    say(f"the mesh with {', '.join(halve)} cells halved")
    f_f, f_f_mesh, shapes_f, n_dofs_f = _refined_mesh(spec, theta_d, halve, edges, say, fine)
    index, macs = pair_by_shapes(shapes_c, shapes_f, threshold=0.8)
    fe_mode = ver["fe_mode"].to_numpy(int) - 1  # paired default-mesh mode of each measured mode (-1: none)
    use = (fe_mode >= 0) & (index[np.clip(fe_mode, 0, None)] >= 0)
    if not use.any():
        raise ModelError(f"mesh_check[{state}]: no measured mode could be followed onto the refined mesh "
                         "(MAC < 0.8 at the measuring points for every paired mode) — check the mesh settings")
    rows = fe_mode[use]
    dlnf = np.log(f_f[index[rows]] / f_c[rows])
    weights = np.asarray(opts.weights or np.ones(len(fe_mode)), float)[use]
    delta = first_order_shift(J_all[rows], dlnf, weights)
    limit = opts.max_parameter_change_pct
    warnings = []
    lost = [i + 1 for i in np.flatnonzero((fe_mode >= 0) & ~use)]
    if lost:
        warnings.append(f"measured mode(s) {', '.join(map(str, lost))}: the paired mode has no partner with "
                        "MAC >= 0.8 on the refined mesh; left out of the estimate")
    params, notes = parameter_changes(par, delta, limit)
    warnings += notes
    raw = None if not edges else {"default_mesh_Hz": f_c_mesh, "refined_mesh_Hz": f_f_mesh}
    table = mode_table(f_c, f_f, index, macs, fe_mode, raw)
    io.write_csv(table, out_csv)
    change = np.full(len(fe_mode), np.nan)
    change[use] = 100 * np.expm1(dlnf)
    budget = error_budget(change, par, opts.budget_fraction, halve)
    doc = {"state": state, "halved": list(halve), "extrapolated_over_edge_levels": edges,
           "budget": budget,
           "n_dofs_default": int(n_dofs_c), "n_dofs_refined": int(n_dofs_f),
           "parameters": params, "max_parameter_change_pct": limit, "warnings": warnings,
           "max_paired_frequency_change_pct": float(100 * np.max(np.abs(np.expm1(dlnf))))}
    io.write_json(out_json, doc)
    for n, p in params.items():
        log(f"mesh_check[{state}]: {n} {p['value']:.4g} -> {p['value_refined_first_order']:.4g} N/m^3 "
            f"({p['change_pct']:+.2f} %; 95 % interval +-{p['ci95_half_width_pct']:.1f} %)")
    say(budget["sentence"])
    for w in warnings:
        log(f"mesh_check[{state}]: WARNING {w}")
    return doc
