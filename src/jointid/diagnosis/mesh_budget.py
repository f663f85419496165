"""Where the mesh's error enters the diagnosis's steps (docs/effects.md, "Every known error counted").

Step 1b, :func:`mesh_budget`: the mesh correction and known error of every mode
(:mod:`jointid.diagnosis.mesh_error`), computed once, at the baseline calibrated on the reference state.
Step 8b, :func:`refit_answer`: an answer that changes the structure (an elastic base instead of a clamp)
changes its modes' mesh error more than the first-order drift follows (coverage case S18: the base mode's
correction is -1.04 % on the clamped baseline and -0.22 % at the fitted foundation; k_foundation's interval
sat 6 % high).  The answer alone is refitted with the mesh error at its own optimum.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jointid.diagnosis.mesh_error import DEFAULT_HALVE, ISOLATE_DOFS, MeshErrors, estimate_mesh_errors, solid_share

__all__ = ["mesh_budget", "answer_mesh_error", "softened_terms", "SOFTENING"]


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

    def estimate() -> MeshErrors:
        sols = diag.solve_states(variant, x)
        index = [p.model_index for p in diag.pair(sols)]
        if diag.system.n_dofs < ISOLATE_DOFS:  # the refined meshes solved in this process: their factorisation
            diag.solver.release_factor()  # is not held beside the solver's (made again on use, 1.1 s by default)
        return estimate_mesh_errors(diag.settings.model, diag.system, diag.data, sols, index,
                                    halve, n_modes=diag.n_modes, lift=diag.lift,
                                    solid=[solid_share(diag.solver, s) for s in sols], log=log)

    # asked before at the same point of the same model and data: recorded ("per_solid": recorded with it)
    return diag.remembered("mesh_errors", (variant.name, np.asarray(x, float), list(halve) + ["per_solid"]),
                           estimate, MeshErrors.to_json, MeshErrors.from_json,
                           said="diagnosis: the mesh error as recorded by an earlier run at the same point")


SOFTENING = 2.0
"""A stiffness term below its coefficient at the mesh error's point divided by this changes the structure."""


def softened_terms(reference_kc: dict, kc: dict) -> list[str]:
    """The stiffness terms whose coefficient in ``kc`` is below their coefficient in ``reference_kc`` divided
    by :data:`SOFTENING` (a term ``kc`` does not have keeps its reference value)."""
    return [t for t, v in reference_kc.items() if v > 0 and float(kc.get(t, v)) < v / SOFTENING]


def answer_mesh_error(diag, fits: dict, answer: str | None, notes: list, log) -> str | None:
    """Step 8b: the reported answer's value and interval with the mesh error at its own optimum.

    The correction is computed at the baseline (step 1b).  An answer that softens a stiffness term to less
    than 1/:data:`SOFTENING` of its coefficient there (an elastic base instead of a clamp: four orders of
    magnitude) changes which parts deform, so its modes' mesh error is not the baseline's, and the
    first-order drift cannot follow.  Then the mesh error is computed again at the answer's optimum and the
    answer alone is refitted from there with it; ``fits`` takes the refit.  The ranking, the weights and
    the support stay as judged at the baseline's correction: judging every candidate at the answer's
    correction (tried at efdde1c) lost more coverage cases than it gained.  Returns the refitted label
    (``+a`` or ``+a+b``), or None when nothing was done."""
    label = None if answer is None else "+" + str(answer).replace(" ", "")
    lead = fits.get(label) if label else None
    refs = [d.mesh_reference for d in diag.data]
    if lead is None or any(r is None or r.gradient is None for r in refs):
        return None
    soft = sorted({t for r, s in zip(refs, lead.ev.solutions) for t in softened_terms(r.gradient["kc"], s.kc)})
    if not soft:
        return None
    log(f"diagnosis: the answer {label[1:]} softens {', '.join(soft)}: its mesh error at its own optimum")
    saved = list(diag.data)
    try:
        diag.data[:] = [replace(d, mesh_reference=None, known_rel=None) for d in saved]
        errors = _estimate_at(diag, lead.variant, lead.x, log)
        errors.apply(diag.data)
        diag.reset_context()  # a fit recorded at the baseline's correction is not this fit
        fits[label] = diag.fit(lead.variant, lead.x, index=lead.ev.index)
    finally:
        diag.data[:] = saved
        diag.reset_context()
    notes.append(f"the answer {label[1:]} softens {', '.join(soft)} to less than 1/{SOFTENING:g} of its "
                 f"coefficient at the baseline: its value and interval were refitted with the mesh error computed "
                 f"at its own optimum (chi-square {lead.chi2:.1f} -> {fits[label].chi2:.1f} there); the ranking "
                 f"was judged at the baseline's mesh error")
    return label


def refit_answer(diag, current, fits: dict, ranking, combos, notes: list, log) -> None:
    """Step 8b for the answer the verdict will name first (:func:`jointid.diagnosis.judging.supported_order`):
    :func:`answer_mesh_error`, and a single's ranking row takes the refit's estimate and 95 % interval."""
    from jointid.diagnosis.judging import supported_order
    from jointid.diagnosis.results import refit_row

    label = answer_mesh_error(diag, fits, next(iter(supported_order(ranking, combos)), None), notes, log)
    at = ranking.index[ranking["effect"] == label[1:]] if label and label.count("+") == 1 else []
    if len(at):
        g = fits[label]
        row = refit_row(g, current, diag.data, 0.05)  # no profiled parameter: only em_preload has one, and it stiffens
        for col in ("estimate", "ci95_low", "ci95_high", "interval_scale"):
            ranking.loc[at[0], col] = row[col]
