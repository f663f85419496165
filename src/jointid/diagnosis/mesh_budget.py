"""Where the mesh's error enters the diagnosis's steps (docs/effects.md, "Every known error counted").

* Step 1b, :func:`mesh_budget`: the mesh correction and known error of every mode
  (:mod:`jointid.diagnosis.mesh_error`), computed at the baseline calibrated on the reference state.
* Step 5b, :func:`repoint`: the answer's refit (the first supported single or pair) that softens a stiffness term to less than half of its
  coefficient at that point (an elastic base instead of a clamp, a compliant rail fixing) changes which
  parts of the structure deform, and so the mesh's error of its modes.  The first-order drift cannot
  follow a change that large (from a bonded joint to a foundation, four orders of magnitude).  The
  correction is computed again at that refit's optimum, and the search and the pairs are repeated with
  it (once).  Measured on
  coverage case S18 (base_support, shapes, the truth on a mesh with every cell halved): the base mode's
  correction is -1.04 % on the clamped baseline and -0.22 % at the fitted foundation; k_foundation was
  2.93e11 [2.81e11, 3.07e11] N/m^3 with the baseline's correction and 2.82e11 [2.74e11, 2.91e11] with the
  refit's, the truth 2.77e11.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jointid.diagnosis.mesh_error import DEFAULT_HALVE, MESH_NOTE, MeshErrors, estimate_mesh_errors

__all__ = ["mesh_budget", "repoint", "softened_terms", "REPOINT_SOFTENING", "REPOINT_CHI2"]

REPOINT_SOFTENING = 2.0
"""A stiffness term below its coefficient at the mesh error's point divided by this is a changed structure."""

REPOINT_CHI2 = 10.0
"""Only a refit whose chi-square is at least this much below the current model's moves the mesh error's point."""


def mesh_budget(diag, base, x0, notes: list, log) -> None:
    """Step 1b: each measured mode's mesh correction and known error at ``x0`` of the variant ``base``
    (:mod:`jointid.diagnosis.mesh_error`), set on the diagnoser's states; a note says what was done."""
    from jointid.config.hashing import mesh_digest
    from jointid.config.typed import ModelSpec

    if all(d.computed_on_mesh == mesh_digest(diag.cfg) for d in diag.data):
        notes.append("the mesh error is not in the budget: the data were computed on this very mesh "
                     "(conditions.yaml computed_on_mesh), so the model has no discretisation error against them")
        return
    if ModelSpec.from_config(diag.cfg).is_mesh_file:
        notes.append("the mesh error is not in the budget: a mesh file cannot be refined here (the model error "
                     "sigma_m holds it)")
        return
    errors = _estimate_at(diag, base, x0, log)
    errors.apply(diag.data)
    notes.append(errors.note(diag.data))


def _estimate_at(diag, variant, x, log) -> MeshErrors:
    """The mesh errors of every state at ``x`` of ``variant``, from the memo when it holds them.  The states
    must not carry a correction (their modes are solved here as the run's mesh gives them)."""
    from jointid.config.typed import ModelSpec

    halve = tuple((diag.cfg.get("diagnosis") or {}).get("mesh_error_halve") or DEFAULT_HALVE)
    key = rec = None
    if diag.memo is not None:  # asked before at the same point of the same model and data: recorded
        key = diag.memo.value_key(diag.context_digest(), "mesh_errors", variant.name, np.asarray(x, float),
                                  list(halve))
        rec = diag.memo.get_value(key)
    if rec is not None:
        log("diagnosis: the mesh error as recorded by an earlier run at the same point")
        return MeshErrors.from_json(rec)
    sols = diag.solve_states(variant, x)
    index = [p.model_index for p in diag.pair(sols)]
    diag.solver.release_factor()  # made again on use: the refined mesh's factorisation is not held beside it
    errors = estimate_mesh_errors(ModelSpec.from_config(diag.cfg), diag.cfg, diag.system, diag.data, sols, index,
                                  halve, n_modes=diag.n_modes, lift=diag.lift, log=log)
    if key is not None:
        diag.memo.put_value(key, errors.to_json())
    return errors


def softened_terms(reference_kc: dict, kc: dict) -> list[str]:
    """The stiffness terms whose coefficient in ``kc`` is below their coefficient in ``reference_kc`` divided
    by :data:`REPOINT_SOFTENING`."""
    return [t for t, v in reference_kc.items() if v > 0 and float(kc.get(t, v)) < v / REPOINT_SOFTENING]


def repoint(diag, current, fits: dict, answer: str, notes: list, log):
    """Step 5b (module doc): when the refit of the answer (``answer``: the first supported single or pair,
    :func:`jointid.diagnosis.judging.supported_order`) fits at least :data:`REPOINT_CHI2` better than
    ``current`` and softens a stiffness term by more than :data:`REPOINT_SOFTENING` in some state, the mesh
    errors are computed again at its optimum and set on the diagnoser's states.  Returns ``current``
    refitted with them (for the search to start again from it), or None when nothing moved."""
    refs = [d.mesh_reference for d in diag.data]
    name = "+" + str(answer).replace(" ", "")
    lead = fits.get(name)
    if lead is None or any(r is None or r.gradient is None for r in refs):
        return None
    if lead.chi2 > current.chi2 - REPOINT_CHI2:
        return None
    soft = sorted({t for r, s in zip(refs, lead.ev.solutions) for t in softened_terms(r.gradient["kc"], s.kc)})
    if not soft:
        return None
    log(f"diagnosis: the {name[1:]} refit softens {', '.join(soft)}: the mesh error again at its optimum")
    diag.data[:] = [replace(d, mesh_reference=None, known_rel=None) for d in diag.data]
    errors = _estimate_at(diag, lead.variant, lead.x, log)
    errors.apply(diag.data)
    diag.reset_context()
    notes[:] = [errors.note(diag.data) if n.startswith(MESH_NOTE) else n for n in notes]
    notes.append(f"the mesh error was computed again at the optimum of the {name[1:]} refit, which softens "
                 f"{', '.join(soft)} to less than 1/{REPOINT_SOFTENING:g} of its coefficient at the baseline: the "
                 f"mesh's error of modes whose structure changes is not the baseline's; the candidates and pairs "
                 f"were scored and refitted again with it")
    return diag.fit(current.variant, current.x, index=current.ev.index)
