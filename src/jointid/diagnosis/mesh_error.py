"""The mesh's error in the diagnosis's error budget (docs/effects.md, "Every known error counted").

The diagnosis fits on the run's own mesh, whose frequencies are too high by a discretisation error
that differs from mode to mode.  Left out, that error is a model error the fit cannot tell from a
missing effect, and it biases the effect's estimate.  Once per diagnosis, at the baseline calibrated
on the reference state, every state is solved again on nested refinements of the mesh, one per class
of ``diagnosis.mesh_error_halve`` (default: every cell bisected along X, then along Y, then along Z;
:func:`jointid.fe.model.build_model`).  The refined modes are followed by MAC at the measuring points,
and the log shifts of the classes are added: for the three axes the sum is, to first order in the
cell sizes, the shift of a uniform refinement (on the coarse test rig the sum is within 4 % of a solve
with every cell halved along all three axes, at a seventh of its DOFs; halving the thickness alone,
as the mesh check does, finds less than half of it).

* Every **model mode** gets a **correction** ``c_m = sum ln(f_refined / f_mesh)``, applied to its
  frequency before the modes are paired, at every point of every fit (:func:`correct`): the fits see
  the refined meshes' frequencies (the discretisation error is a bias with a known sign: a nested
  refinement can only lower the frequencies).  The correction belongs to the model mode, found again
  at each point by MAC at the probe against the shapes where it was computed (MAC²-weighted, so it
  moves continuously), so two close modes that change order or pairing during a fit keep their own
  corrections.
* Every **measured mode** gets a **known error** ``k_j = |exp(c_m) - 1|`` of its paired model mode,
  beside the noise: what the refined mesh itself still misses.  For a sequence of meshes whose error
  contracts by a ratio ``r <= 0.5`` per halving (0.39 - 0.49 on this rig's edge levels,
  docs/reconstruction.md), the refined mesh's remaining error is at most the step it just took,
  ``r / (1 - r) |c_m| <= |c_m|``.

A mode the refined mesh cannot follow (MAC < 0.8) takes the largest shift of its state, and an
unpaired measured mode the largest known error of the paired ones: the mesh error of a mode the check
cannot see is not taken to be zero.  The corrections are computed
once, at one parameter point (the discretisation error moves little with the joints); states whose
model coefficients are equal there (e.g. without an enabled effect that tells them apart) share one
refined solve.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MeshErrors", "correct", "estimate_mesh_errors", "mesh_budget", "FOLLOW_MAC"]

FOLLOW_MAC = 0.8
"""A refined-mesh mode follows a model mode when their MAC at the measuring points is at least this."""

DEFAULT_HALVE = ("length", "thickness", "width")
"""The cell classes halved one at a time (``diagnosis.mesh_error_halve``): the three axes, whose summed
shifts are a uniform refinement's to first order."""


@dataclass
class MeshErrors:
    """The mesh errors of one diagnosis, per state: the log correction of every model mode at the point
    they were computed with the model shapes that identify those modes, and per measured mode the
    correction of its paired model mode and its known error."""

    halved: tuple
    shift: list = field(default_factory=list)  # per state (n_measured,): ln(f_refined / f_mesh) of its model mode
    known: list = field(default_factory=list)  # per state (n_measured,): |f_refined / f_mesh - 1|
    n_dofs: tuple = (0, 0)  # the mesh's and the largest refined mesh's DOFs
    model_shift: list = field(default_factory=list)  # per state (n_model,): every model mode's correction
    shapes: list = field(default_factory=list)  # per state (n_labels, n_model): the model shapes at the probe

    def apply(self, data: list) -> None:
        """Replace every state of the list ``data`` (aligned with this) by a copy with its correction and
        known error (the caller's state objects are left as they were)."""
        from dataclasses import replace

        data[:] = [replace(d, mesh_reference=(p, c), known_rel=k)
                   for d, p, c, k in zip(data, self.shapes, self.model_shift, self.known)]

    def note(self, data) -> str:
        """One sentence for the notes of the diagnosis."""
        worst = max((float(np.max(k)) for k in self.known if len(k)), default=0.0)
        return (f"mesh error in the budget: each state solved again with the {', '.join(self.halved)} cells "
                f"halved, one at a time, the shifts added ({self.n_dofs[0]} -> at most {self.n_dofs[1]} DOFs); "
                f"every measured "
                f"mode's model frequency is corrected by its change (at most {100 * worst:.2f} %) and the same "
                f"amount is counted as a known error beside the noise (the refined mesh's own error)")

    def to_json(self) -> dict:
        """Exact JSON form (floats as hex), for :meth:`jointid.diagnosis.memo.FitMemo.put_value`; no wall-clock
        time in it (the memo is kept in the subspace file, which must be byte-identical run to run)."""
        hexes = lambda a: [float(v).hex() for v in np.ravel(a)]  # noqa: E731
        return {"halved": list(self.halved), "n_dofs": list(self.n_dofs),
                "shift": [hexes(c) for c in self.shift], "known": [hexes(k) for k in self.known],
                "model_shift": [hexes(c) for c in self.model_shift],
                "shapes": [{"shape": list(np.shape(p)), "values": hexes(p)} for p in self.shapes]}

    @classmethod
    def from_json(cls, rec: dict) -> "MeshErrors":
        """The inverse of :meth:`to_json`."""
        arr = lambda v: np.array([float.fromhex(x) for x in v])  # noqa: E731
        return cls(tuple(rec["halved"]), [arr(c) for c in rec["shift"]], [arr(k) for k in rec["known"]],
                   tuple(rec["n_dofs"]), [arr(c) for c in rec["model_shift"]],
                   [arr(p["values"]).reshape(p["shape"]) for p in rec["shapes"]])

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

    from jointid.diagnosis.terms import build_system
    from jointid.fe.model import build_model
    from jointid.fe.modal import release_heap

    t0 = time.time()
    log(f"diagnosis: the mesh error: each state again with the {', '.join(halve)} cells halved, one at a time")
    out = MeshErrors(tuple(halve), n_dofs=(int(system.n_dofs), 0))
    total = [np.zeros(len(sol.freqs_Hz)) for sol in sols]
    for cls in halve:
        fine = build_system(build_model(spec, halve=(cls,)), cfg)
        out.n_dofs = (out.n_dofs[0], max(out.n_dofs[1], int(fine.n_dofs)))
        done = []  # (coefficients, shift) of the states solved: states at equal coefficients share one solve
        for k, sol in enumerate(sols):
            same = next((c for (kc, mc), c in done if kc == sol.kc and mc == sol.mc), None)
            shift = _class_shift(fine, sol, n_modes) if same is None else same
            done.append(((sol.kc, sol.mc), shift))
            total[k] = total[k] + shift
        del fine
        release_heap()
    for d, sol, idx, model_shift in zip(data, sols, index, total):
        idx = np.asarray(idx, int)
        paired = model_shift[idx[idx >= 0]]  # an unpaired measured mode: the largest of the paired ones
        worst = paired[np.argmax(np.abs(paired))] if len(paired) else 0.0
        shift = np.where(idx >= 0, model_shift[np.maximum(idx, 0)], worst)
        out.model_shift.append(model_shift)
        out.shapes.append(np.asarray(sol.shapes, float))
        out.shift.append(shift)
        out.known.append(np.abs(np.expm1(shift)))
        log(f"diagnosis: mesh error of {d.name}: " + ", ".join(f"{100 * np.expm1(c):+.2f} %" for c in shift))
    log(f"diagnosis: the mesh error in {time.time() - t0:.0f} s")  # the log's, not the results' (byte-identical)
    return out


def _class_shift(fine, sol, n_modes: int) -> np.ndarray:
    """One state's log shift of every model mode when the cells of one class are halved: the refined
    modes followed by MAC at the probe; a mode not followed takes the state's largest shift."""
    from jointid.correlate.pairing import pair_by_shapes
    from jointid.fe.modal import solve_modes

    modes = solve_modes(fine.K(sol.kc), fine.M(sol.mc), n_modes, fixed=fine.fixed)
    follow, _ = pair_by_shapes(sol.shapes, fine.probe @ modes.phi, threshold=FOLLOW_MAC)
    shift = np.full(len(sol.freqs_Hz), np.nan)
    seen = np.flatnonzero(np.asarray(follow) >= 0)
    shift[seen] = np.log(modes.freqs_Hz[np.asarray(follow)[seen]] / sol.freqs_Hz[seen])
    ok = np.isfinite(shift)
    worst = shift[ok][np.argmax(np.abs(shift[ok]))] if ok.any() else 0.0
    return np.where(ok, shift, worst)


def correct(d, sol):
    """The solution ``sol`` of state ``d`` with the mesh's correction applied to its frequencies
    (``sol`` itself where the state has none).  Each model mode takes the corrections of the modes at
    the point they were computed, weighted by MAC² at the probe: a mode that continues one of them
    (MAC near 1) takes its correction, two close modes that mix take a blend, and the correction moves
    continuously with the parameters (a hard match would jump when a MAC crosses a threshold, and the
    fit's objective with it).  The correction so stays with the model mode when close modes change
    order or pairing during a fit."""
    if d.mesh_reference is None:
        return sol
    from dataclasses import replace

    from jointid.correlate.pairing import mac

    shapes, model_shift = d.mesh_reference
    w = mac(shapes, sol.shapes) ** 2  # (n_reference, n_modes)
    total = w.sum(axis=0)
    c = np.where(total > 1e-12, (w.T @ model_shift) / np.maximum(total, 1e-12), float(np.mean(model_shift)))
    return replace(sol, freqs_Hz=sol.freqs_Hz * np.exp(c))


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
    halve = tuple((diag.cfg.get("diagnosis") or {}).get("mesh_error_halve") or DEFAULT_HALVE)
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
