"""The mesh's error in the diagnosis's error budget (docs/effects.md, "Every known error counted").

The diagnosis fits on the run's own mesh, whose frequencies are too high by a discretisation error
that differs from mode to mode.  Left out, that error is a model error the fit cannot tell from a
missing effect, and it biases the effect's estimate.  Once per diagnosis, at the baseline calibrated
on the reference state, every state is solved again on a nested refinement of the mesh (the cells of
``mesh_check.halve`` bisected, :func:`jointid.fe.model.build_model`), the refined modes are followed
by MAC at the measuring points, and each measured mode gets:

* a **correction** ``c_j = ln(f_refined / f_mesh)`` of its paired model mode, added to the model's log
  frequency in every fit: the fits then see the refined mesh's frequencies (the discretisation error is
  a bias with a known sign: a nested refinement can only lower the frequencies);
* a **known error** ``k_j = |exp(c_j) - 1|`` beside the noise: what the refined mesh itself still
  misses.  For a sequence of meshes whose error contracts by a ratio ``r <= 0.5`` per halving (0.39 -
  0.49 on this rig's edge levels, docs/reconstruction.md), the refined mesh's remaining error is at most
  the step it just took, ``r / (1 - r) |c_j| <= |c_j|``.

A measured mode whose partner cannot be followed (MAC < 0.8) takes the largest correction and known
error of its state: the mesh error of a mode the check cannot see is not taken to be zero.  The
corrections are per measured mode, so they follow the measured mode if a fit re-pairs it; they are
computed once, at one parameter point (the discretisation error moves little with the joints).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MeshErrors", "estimate_mesh_errors", "mesh_budget", "FOLLOW_MAC"]

FOLLOW_MAC = 0.8
"""A refined-mesh mode follows a model mode when their MAC at the measuring points is at least this."""


@dataclass
class MeshErrors:
    """The mesh errors of one diagnosis: per state, the correction (log) and known error per measured mode."""

    halved: tuple
    shift: list = field(default_factory=list)  # per state (n_measured,): ln(f_refined / f_mesh)
    known: list = field(default_factory=list)  # per state (n_measured,): |f_refined / f_mesh - 1|
    n_dofs: tuple = (0, 0)  # the mesh's and the refined mesh's DOFs
    seconds: float = 0.0

    def apply(self, data: list) -> None:
        """Replace every state of the list ``data`` (aligned with this) by a copy with its correction and
        known error (the caller's state objects are left as they were)."""
        from dataclasses import replace

        data[:] = [replace(d, mesh_shift=c, known_rel=k) for d, c, k in zip(data, self.shift, self.known)]

    def note(self, data) -> str:
        """One sentence for the notes of the diagnosis."""
        worst = max((float(np.max(k)) for k in self.known if len(k)), default=0.0)
        return (f"mesh error in the budget: each state solved again with the {', '.join(self.halved)} cells "
                f"halved ({self.n_dofs[0]} -> {self.n_dofs[1]} DOFs, {self.seconds:.0f} s); every measured "
                f"mode's model frequency is corrected by its change (at most {100 * worst:.2f} %) and the same "
                f"amount is counted as a known error beside the noise (the refined mesh's own error)")

    def to_json(self) -> dict:
        """Exact JSON form (floats as hex), for :meth:`jointid.diagnosis.memo.FitMemo.put_value`."""
        return {"halved": list(self.halved), "n_dofs": list(self.n_dofs), "seconds": float(self.seconds),
                "shift": [[float(v).hex() for v in c] for c in self.shift],
                "known": [[float(v).hex() for v in k] for k in self.known]}

    @classmethod
    def from_json(cls, rec: dict) -> "MeshErrors":
        """The inverse of :meth:`to_json`."""
        return cls(tuple(rec["halved"]), [np.array([float.fromhex(v) for v in c]) for c in rec["shift"]],
                   [np.array([float.fromhex(v) for v in k]) for k in rec["known"]], tuple(rec["n_dofs"]),
                   float(rec["seconds"]))

    def record(self, data) -> list[dict]:
        """Rows ``state, mode, mesh_correction_pct, mesh_known_error_pct`` for a table."""
        rows = []
        for d, c, k in zip(data, self.shift, self.known):
            for j in range(len(c)):
                rows.append({"state": d.name, "mode": j + 1, "mesh_correction_pct": 100 * float(np.expm1(c[j])),
                             "mesh_known_error_pct": 100 * float(k[j])})
        return rows


def estimate_mesh_errors(spec, cfg: dict, system, data, sols, index, halve: tuple, *, n_modes: int,
                         log=print) -> MeshErrors:
    # many parameters: the model (spec, cfg, system), the states with their solutions and pairing, the refinement
    """Each measured mode's mesh correction and known error (see the module doc).

    Parameters
    ----------
    spec : jointid.config.typed.ModelSpec
        The run's model (the parametric rig; a mesh file cannot be refined).
    cfg : dict
        The configuration the diagnosis system was built with (:func:`jointid.diagnosis.terms.build_system`).
    system : jointid.diagnosis.terms.System
        The diagnosis system on the run's mesh.
    data : list of StateData
    sols : list of jointid.fe.reduced.Solution
        The modes of every state at the parameter point, on the run's mesh.
    index : list of arrays
        Per state, the model mode paired with each measured mode (-1: none).
    halve : tuple of str
        The cells bisected (``mesh_check.halve``).
    n_modes : int
        Modes solved on the refined mesh.
    """
    import time

    from jointid.correlate.pairing import pair_by_shapes
    from jointid.diagnosis.terms import build_system
    from jointid.fe.model import build_model
    from jointid.fe.modal import release_heap, solve_modes

    t0 = time.time()
    log(f"diagnosis: the mesh error: each state again with the {', '.join(halve)} cells halved")
    fine = build_system(build_model(spec, halve=tuple(halve)), cfg)
    out = MeshErrors(tuple(halve), n_dofs=(int(system.n_dofs), int(fine.n_dofs)))
    for d, sol, idx in zip(data, sols, index):
        kc, mc = sol.kc, sol.mc
        modes = solve_modes(fine.K(kc), fine.M(mc), n_modes, fixed=fine.fixed)
        shapes_f = fine.probe @ modes.phi
        follow, _ = pair_by_shapes(sol.shapes, shapes_f, threshold=FOLLOW_MAC)
        idx = np.asarray(idx, int)
        shift = np.full(len(idx), np.nan)
        for j, m in enumerate(idx):
            if m >= 0 and follow[m] >= 0:
                shift[j] = np.log(modes.freqs_Hz[follow[m]] / sol.freqs_Hz[m])
        seen = np.isfinite(shift)
        worst = shift[seen][np.argmax(np.abs(shift[seen]))] if seen.any() else 0.0
        shift = np.where(seen, shift, worst)
        out.shift.append(shift)
        out.known.append(np.abs(np.expm1(shift)))
        log(f"diagnosis: mesh error of {d.name}: " + ", ".join(f"{100 * np.expm1(c):+.2f} %" for c in shift))
    del fine
    release_heap()
    out.seconds = time.time() - t0
    return out


def mesh_budget(diag, base, x0, notes: list, log) -> None:
    """Step 1b: each measured mode's mesh correction and known error at ``x0``
    (:mod:`jointid.diagnosis.mesh_error`), set on the diagnoser's states; a note says what was done."""
    from jointid.config.typed import ModelSpec

    from jointid.config.hashing import mesh_digest

    if all(d.computed_on_mesh == mesh_digest(diag.cfg) for d in diag.data):
        notes.append("the mesh error is not in the budget: the data were computed on this very mesh "
                     "(conditions.yaml computed_on_mesh), so the model has no discretisation error against them")
        return
    spec = ModelSpec.from_config(diag.cfg)
    if spec.is_mesh_file:
        notes.append("the mesh error is not in the budget: a mesh file cannot be refined here (the model error "
                     "sigma_m holds it)")
        return
    halve = tuple((diag.cfg.get("mesh_check") or {}).get("halve") or ("thickness",))
    key = rec = None
    if diag.memo is not None:  # asked before at the same point of the same model and data: recorded
        key = diag.memo.value_key(diag.context_digest(), "mesh_errors", np.asarray(x0, float), list(halve))
        rec = diag.memo.get_value(key)
    if rec is not None:
        errors = MeshErrors.from_json(rec)
        log("diagnosis: the mesh error as recorded by an earlier run at the same point")
    else:
        sols = diag.solve_states(base, x0)
        index = [p.model_index for p in diag.pair(sols)]
        diag.solver.release_factor()  # made again on use: the refined mesh's factorisation is not held beside it
        errors = estimate_mesh_errors(spec, diag.cfg, diag.system, diag.data, sols, index, halve,
                                      n_modes=diag.n_modes, log=log)
        if key is not None:
            diag.memo.put_value(key, errors.to_json())
    errors.apply(diag.data)
    notes.append(errors.note(diag.data))
