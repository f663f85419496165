"""What a fitted hypothesis predicts for measurements not made yet (docs/reconstruction.md, "The
measurement that would narrow the reconstruction").

:func:`measurement_predictions` adds to a hypothesis's record (:func:`jointid.reconstruction.hypotheses.fit_hypothesis`)
what the ranking job needs to judge candidate measurements (:mod:`jointid.reconstruction.next_measurement`):

* ``moving_mass_kg``: the mass resting on the joints (table, carriages, motor primaries, and any mass an
  effect of the hypothesis adds), the weight of the moving part over g;
* per state, ``static_stiffness_N_per_m``: the static drive-point stiffness ``1 / H(0)`` at
  ``harmonic.drive_point`` in each direction x, y, z (one factorisation of the full stiffness at the
  fitted coefficients, one solve with three right-hand sides), the load spread and the response averaged
  over Table 1's patch (``harmonic.patch_diameter_m``, :func:`jointid.fe.patch.patch_probe`): a point load's
  local flexibility grows without bound as the mesh is refined (``static_load`` says which was used);
* per state, ``paired_shapes``: the model's shape at every measuring DOF (``probe_labels``) of the
  model mode paired with each measured mode (unit RMS over the DOFs; ``None`` for an unpaired mode), and
  ``shapes_measured``, whether the state's dataset has shapes.

No damping is predicted: the hypotheses share one nominal modal damping ratio, so a measured damping
ratio could not tell them apart.
"""

from __future__ import annotations

import numpy as np

from jointid.diagnosis.terms import baseline_coefficients
from jointid.fe.modal import factorize_pencil
from jointid.geometry.rig import PART_IDS

__all__ = ["measurement_predictions", "moving_mass_kg", "static_stiffness"]

DIRECTIONS = ("x", "y", "z")


def _y_rows(system) -> np.ndarray:
    """The y rows of the body resting on the joints (table, carriages and their shared nodes); all
    y rows for a model without parts."""
    part = getattr(system.model, "dof_part", None)
    n = system.n_dofs
    if part is None or len(part) * 3 != n or "carried_mass_kg" in system.model.meta:
        return np.arange(1, n, 3)
    body = np.isin(part, [PART_IDS["carriage"], PART_IDS["table"]]) | (part < 0)
    return 3 * np.flatnonzero(body) + 1


def moving_mass_kg(system, variant, x, mc: dict) -> float:
    """The mass resting on the joints at mass coefficients ``mc`` of ``variant`` at ``x``:
    ``system.carried_mass_kg`` (the configuration's parts and motors) plus what the effects change in
    the mass terms on the carried body (an added mass on the table)."""
    theta, _ = variant.unpack(x)
    _, mc0 = baseline_coefficients(system, variant.spec, theta)
    rows = _y_rows(system)
    ey = np.zeros(system.n_dofs)
    ey[1::3] = 1.0
    out = float(system.carried_mass_kg)
    for name in sorted(set(mc) | set(mc0)):
        dv = float(mc.get(name, 0.0)) - float(mc0.get(name, 0.0))
        if dv != 0.0 and name in system.mass:
            out += dv * float((system.mass[name] @ ey)[rows].sum())
    return out


def static_stiffness(solver, kc: dict, mc: dict, P) -> np.ndarray:
    """``1 / H_ii(0)`` for the load / response rows ``P`` (sparse, ``(k, n_free)``) in N/m: one
    factorisation of ``K`` on the free DOFs of the reduced solver's pencil, one solve.  NaN where ``K`` is
    singular (a rigid-body mode)."""
    k = P.shape[0]
    solver.settle()  # a factorisation under way records the pencil's ordering first
    try:
        fac = factorize_pencil(solver.pencil, kc, mc, 0.0, solver.backend)
    except Exception:  # noqa: BLE001 - a singular stiffness has no static compliance
        return np.full(k, np.nan)
    try:
        U = fac.solve(np.asarray(P.T.todense(), float))
        H = np.asarray(P @ U).reshape(k, k)
    finally:
        fac.free()
    h = np.diag(H)
    return np.where(h > 0, 1.0 / np.where(h > 0, h, 1.0), np.nan)


def measurement_predictions(diag, fit, data) -> dict:
    """The record's ``predictions`` (module doc) of ``fit`` (a certified fit of ``diag``) on ``data``."""
    system = fit.variant.system
    labels = list(system.labels)
    h = fit.variant.settings.response
    point = h.drive_point
    dirs = [d for d in DIRECTIONS if f"{point}:{d}" in labels]
    rows = [labels.index(f"{point}:{d}") for d in dirs]
    solver = diag.solver
    P, load = None, "point"
    if solver is not None and rows:
        # the solver keeps its factorisation beside the static one: released here, the next certificate's
        # checks made it again (three times per run of the paper's hypotheses, 1.1 s each; +115 MB on its run model)
        P, load = _drive_rows(system, solver, point, dirs, rows, h.patch_diameter_m)
    states = []
    for si, d in enumerate(data):
        sol = fit.ev.solutions[si]
        kc, mc = sol.kc, sol.mc
        k = static_stiffness(solver, kc, mc, P) if P is not None else np.full(len(rows), np.nan)
        phi = np.asarray(sol.shapes, float)
        shapes = []
        for j in np.asarray(fit.ev.index[si]):
            if j < 0:
                shapes.append(None)
                continue
            v = phi[:, int(j)]
            rms = float(np.sqrt(np.mean(v ** 2)))
            shapes.append([float(a) for a in (v / rms if rms > 0 else v)])
        states.append({"state": d.name,
                       "static_stiffness_N_per_m": {f"{point}:{dd}": float(kk) for dd, kk in zip(dirs, k)},
                       "shapes_measured": bool(d.shapes is not None and np.isfinite(d.shapes).any()),
                       "paired_shapes": shapes})
    mc_first = fit.ev.solutions[0].mc
    return {"moving_mass_kg": moving_mass_kg(system, fit.variant, fit.x, mc_first), "drive_point": point,
            "static_load": load, "probe_labels": labels, "states": states}


def _drive_rows(system, solver, point: str, dirs: list[str], rows: list[int], diameter_m: float):
    """The load / response rows of the static solve on the solver's free DOFs, and how the load is
    applied: over a disc of ``diameter_m`` (:func:`jointid.fe.patch.patch_probe`, ``"patch <d> mm"``), or at
    the probe's point where there is no patch or the model cannot give one (``"point"``)."""
    if diameter_m > 0:
        try:
            from jointid.fe.patch import patch_probe

            R = patch_probe(system.model, [point], diameter_m).tocsr()[["xyz".index(d) for d in dirs]]
            return R[:, solver.free].tocsr(), f"patch {1e3 * diameter_m:g} mm"
        except Exception:  # noqa: BLE001 - e.g. a mesh-file model without a top surface at the point
            pass
    return solver.P[rows], "point"
