"""Where the mesh's error enters the diagnosis's steps (docs/effects.md, "Every known error counted").

Step 1b, :func:`mesh_budget`: the mesh correction and known error of every mode
(:mod:`jointid.diagnosis.mesh_error`), computed once, at the baseline calibrated on the reference state.
An answer that changes the structure (an elastic base instead of a clamp) changes its modes' mesh error
more than the first-order drift follows: on coverage case S18 the base mode's correction is -1.04 % on the
clamped baseline and -0.22 % at the fitted foundation, and k_foundation's interval sits 6 % high
(docs/effects.md says what was tried).
"""

from __future__ import annotations

import numpy as np

from jointid.diagnosis.mesh_error import DEFAULT_HALVE, MeshErrors, estimate_mesh_errors, solid_share

__all__ = ["mesh_budget"]


def mesh_budget(diag, base, x0, notes: list, log) -> None:
    """Step 1b: each measured mode's mesh correction and known error at ``x0`` of the variant ``base``
    (:mod:`jointid.diagnosis.mesh_error`), set on the diagnoser's states; a note says what was done."""
    if all(d.computed_on_mesh == diag.settings.mesh_digest for d in diag.data):
        notes.append("the mesh error is not in the budget: the data were computed on this very mesh "
                     "(conditions.yaml computed_on_mesh), so the model has no discretisation error against them")
        return
    if diag.settings.model.is_mesh_file:
        notes.append("the mesh error is not in the budget: a mesh file cannot be refined here (the model error "
                     "sigma_m holds it)")
        return
    errors = _estimate_at(diag, base, x0, log)
    errors.apply(diag.data)
    notes.append(errors.note(diag.data))


def _estimate_at(diag, variant, x, log) -> MeshErrors:
    """The mesh errors of every state at ``x`` of ``variant``, from the memo when it holds them.  The states
    must not carry a correction (their modes are solved here as the run's mesh gives them)."""
    halve = diag.settings.mesh_error_halve or DEFAULT_HALVE
    key = rec = None
    if diag.memo is not None:  # asked before at the same point of the same model and data: recorded
        key = diag.memo.value_key(diag.context_digest(), "mesh_errors", variant.name, np.asarray(x, float),
                                  list(halve) + ["per_solid"])  # "per_solid": recorded with it
        rec = diag.memo.get_value(key)
    if rec is not None:
        log("diagnosis: the mesh error as recorded by an earlier run at the same point")
        return MeshErrors.from_json(rec)
    sols = diag.solve_states(variant, x)
    index = [p.model_index for p in diag.pair(sols)]
    diag.solver.release_factor()  # made again on use: the refined mesh's factorisation is not held beside it
    errors = estimate_mesh_errors(diag.settings.model, diag.system, diag.data, sols, index,
                                  halve, n_modes=diag.n_modes, lift=diag.lift,
                                  solid=[solid_share(diag.solver, s) for s in sols], log=log)
    if key is not None:
        diag.memo.put_value(key, errors.to_json())
    return errors
