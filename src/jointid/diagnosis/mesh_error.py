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

* Where a fit moves a state's coefficients away from the point where the correction was computed (an
  effect that stiffens the joints of one state only, e.g. ``em_preload``), the mesh error moves with
  them.  Its **first-order change** is known: ``d c_m / d coef_t = (e_t,refined - e_t,mesh) / 2`` with
  ``e_t = phi^T K_t phi / lambda`` for a stiffness term and ``-phi^T M_t phi`` for a mass term (the
  mode's energy share of the term per unit coefficient, mass-normalised ``phi``), summed over the
  classes like the shifts.  :func:`drift` gives it at every fit point, and :func:`correct` adds it to
  the correction (kept between zero and twice the state's largest correction: a refinement only
  lowers a frequency).  Half of it is counted as a known error of the row's own, independent between
  states (the first order holds to about a third of the change, tests/test_mesh_error.py), beside the
  part the states share (:func:`jointid.diagnosis.fitting.Diagnoser.evaluate`).  So a difference
  between states is corrected for the mesh error that differs between them, and not judged at the
  noise alone.

* A mode the reference point does not have (an elastic base's own mode: on coverage case S18 the modes
  at the clamped reference have MAC <= 0.1 with it) cannot take the correction of a reference mode.  The
  discretisation error sits in the solids' strain energy (the spring layers are exact), so such a mode
  takes its **solids' energy share** ``s_m`` times the state's correction per unit share (the median of
  ``c_r / s_r`` over the reference modes): measured on S18, -0.30 % against -0.22 % on the refined meshes,
  where the MAC-weighted correction gave -1 to -3 %.  The two are blended by how much of the mode the
  reference modes hold (the sum of its MAC² with them, full at 0.64 and above, :func:`correct`).

A mode the refined mesh cannot follow (MAC < 0.8) takes the largest shift of its state, and an
unpaired measured mode the largest known error of the paired ones: the mesh error of a mode the check
cannot see is not taken to be zero.  The corrections are computed
once, at one parameter point (the discretisation error moves little with the joints); states whose
model coefficients are equal there (e.g. without an enabled effect that tells them apart) share one
refined solve.  The refined meshes are built and solved in a process of their own (:mod:`jointid.isolate`,
:func:`refined_shifts`), which returns only the shifts: each is about twice the run's mesh, and on the
default 6 mm cells the diagnosis's largest process fell from 2.51 GiB to 2.0 GiB (the same numbers, to the bit).
A mesh below :data:`ISOLATE_DOFS` is refined in the diagnosis's own process.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

__all__ = ["ISOLATE_DOFS", "MeshErrors", "MeshReference", "Point", "refined_shifts", "correct", "drift", "estimate_mesh_errors", "shape_known", "solid_share",
           "FOLLOW_MAC"]

FOLLOW_MAC = 0.8
"""A refined-mesh mode follows a model mode when their MAC at the measuring points is at least this."""

ISOLATE_DOFS = 40000
"""From this many DOFs of the run's mesh on, the refined meshes are solved in a process of their own
(:func:`estimate_mesh_errors`, module doc); below, in the diagnosis's own process: each refined mesh then takes
well under 1 GB, and a child's start costs about 1.2 s of imports (the synthetic diagnoses of the tests, on the
coarse rig's 17 472 DOFs).  The same numbers either way (tests/test_mesh_error.py)."""

DEFAULT_HALVE = ("length", "thickness", "width")
"""The cell classes halved one at a time (``diagnosis.mesh_error_halve``): the three axes, whose summed
shifts are a uniform refinement's to first order."""


class ClassShift(NamedTuple):
    """One halving class's change of one state's model modes (:func:`_class_shift`)."""

    shift: np.ndarray  # (n_model,) log frequency shift; a mode not followed: the state's largest
    shares: tuple  # ({stiffness term: (n_model,)}, {mass term: (n_model,)}) of the refined modes, or two empty dicts
    shape_change: np.ndarray  # (n_labels, n_model): refined probe shape scaled to the model's, less the model's
    lost: np.ndarray  # (n_model,): known relative shape error of a mode not followed (0 where followed)


@dataclass(frozen=True)
class MeshReference:
    """One state's mesh correction at the point it was computed (:attr:`StateData.mesh_reference`): the model
    shapes at the probe that identify the modes, their log frequency corrections, the corrections' gradient in
    the coefficients (None: not known), and the change of each mode's probe shape on the refined meshes with
    the known error of a mode no refined mesh could follow (None: shapes not corrected)."""

    shapes: np.ndarray  # (n_labels, n_model)
    model_shift: np.ndarray  # (n_model,)
    gradient: dict | None = None
    shape_shift: np.ndarray | None = None  # (n_labels, n_model), in the units of ``shapes``
    shape_floor: np.ndarray | None = None  # (n_model,): relative to the mode's RMS; 0 where followed
    per_solid: float | None = None  # the state's log correction per unit solids' energy share (None: not known)


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
    gradient: list = field(default_factory=list)  # per state: d(model_shift)/d(coefficient) (:func:`drift`):
    # {"kc": {term: coefficient at the reference}, "mc": {...}, "gk": {term: (n_model,)}, "gm": {term: (n_model,)}}
    shape_shift: list = field(default_factory=list)  # per state (n_labels, n_model): refined minus mesh probe shape
    shape_floor: list = field(default_factory=list)  # per state (n_model,): known shape error of a mode not followed
    per_solid: list = field(default_factory=list)  # per state: log correction per unit solids' energy share

    def apply(self, data: list) -> None:
        """Replace every state of the list ``data`` (aligned with this) by a copy with its correction and
        known error (the caller's state objects are left as they were)."""
        from dataclasses import replace

        n = len(self.shapes)
        grads = self.gradient or [None] * n
        dshape = self.shape_shift or [None] * n
        floor = self.shape_floor or [None] * n
        per = self.per_solid or [None] * n
        data[:] = [replace(d, mesh_reference=MeshReference(p, c, g, ds, fl, ps), known_rel=k)
                   for d, p, c, k, g, ds, fl, ps in zip(data, self.shapes, self.model_shift, self.known, grads,
                                                         dshape, floor, per)]

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
        grad = [{"kc": {t: float(v).hex() for t, v in g["kc"].items()},
                 "mc": {t: float(v).hex() for t, v in g["mc"].items()},
                 "gk": {t: hexes(v) for t, v in g["gk"].items()}, "gm": {t: hexes(v) for t, v in g["gm"].items()}}
                for g in self.gradient]
        return {"halved": list(self.halved), "n_dofs": list(self.n_dofs),
                "shift": [hexes(c) for c in self.shift], "known": [hexes(k) for k in self.known],
                "model_shift": [hexes(c) for c in self.model_shift],
                "shapes": [{"shape": list(np.shape(p)), "values": hexes(p)} for p in self.shapes],
                "gradient": grad,
                "shape_shift": [{"shape": list(np.shape(p)), "values": hexes(p)} for p in self.shape_shift],
                "shape_floor": [hexes(f) for f in self.shape_floor],
                "per_solid": [None if v is None else float(v).hex() for v in self.per_solid]}

    @classmethod
    def from_json(cls, rec: dict) -> "MeshErrors":
        """The inverse of :meth:`to_json`."""
        arr = lambda v: np.array([float.fromhex(x) for x in v])  # noqa: E731
        grad = [{"kc": {t: float.fromhex(v) for t, v in g["kc"].items()},
                 "mc": {t: float.fromhex(v) for t, v in g["mc"].items()},
                 "gk": {t: arr(v) for t, v in g["gk"].items()}, "gm": {t: arr(v) for t, v in g["gm"].items()}}
                for g in rec.get("gradient", [])]
        mats = lambda key: [arr(p["values"]).reshape(p["shape"]) for p in rec.get(key, [])]  # noqa: E731
        return cls(tuple(rec["halved"]), [arr(c) for c in rec["shift"]], [arr(k) for k in rec["known"]],
                   tuple(rec["n_dofs"]), [arr(c) for c in rec["model_shift"]], mats("shapes"), grad,
                   mats("shape_shift"), [arr(f) for f in rec.get("shape_floor", [])],
                   [None if v is None else float.fromhex(v) for v in rec.get("per_solid", [])])

    def record(self, data) -> list[dict]:
        """Rows ``state, mode, mesh_correction_pct, mesh_known_error_pct`` for a table."""
        rows = []
        for d, c, k in zip(data, self.shift, self.known):
            for j in range(len(c)):
                rows.append({"state": d.name, "mode": j + 1, "mesh_correction_pct": 100 * float(np.expm1(c[j])),
                             "mesh_known_error_pct": 100 * float(k[j])})
        return rows


def estimate_mesh_errors(spec, system, data, sols, index, halve: tuple, *, n_modes: int,
                         lift=None, solid=None, log=print) -> MeshErrors:
    # many parameters: the model (spec, system), the states with their solutions and pairing, the refinement
    """Each measured mode's mesh correction and known error (see the module doc).

    Parameters
    ----------
    spec, system : ModelSpec, jointid.diagnosis.terms.System
        The run's model (the parametric rig; a mesh file cannot be refined; the diagnosis system was built
        with it), and that system on the run's mesh.
    data : list of StateData
    sols : list of jointid.fe.reduced.Solution
        The modes of every state at the parameter point, on the run's mesh.
    index : list of arrays
        Per state, the model mode paired with each measured mode (-1: none).
    halve : tuple of str
        The cells bisected (``mesh_check.halve``).
    n_modes : int
        Modes solved on the refined mesh.
    lift : callable, optional
        ``lift(Y)``: the full-space modes of reduced vectors ``Y`` (the diagnosis's reduced solver); with it
        the first-order change of the correction with the coefficients is estimated too (:func:`drift`).
    solid : list of arrays, optional
        Per state, every model mode's solids' energy share (:func:`solid_share`); with it each state's
        correction per unit share is kept, for the modes the reference point does not have (module doc).
    """
    import time

    from jointid import isolate

    t0 = time.time()
    log(f"diagnosis: the mesh error: each state again with the {', '.join(halve)} cells halved, one at a time")
    total = [np.zeros(len(sol.freqs_Hz)) for sol in sols]
    dshape = [np.zeros(np.shape(sol.shapes)) for sol in sols]  # summed over the classes like the shifts
    floor = [np.zeros(len(sol.freqs_Hz)) for sol in sols]
    coarse = [None if lift is None else _shares(system, lift(sol.Y), sol.lam, sol) for sol in sols]
    grads = [None if c is None else {"kc": dict(sol.kc), "mc": dict(sol.mc),
                                     "gk": {t: np.zeros(len(sol.freqs_Hz)) for t in c[0]},
                                     "gm": {t: np.zeros(len(sol.freqs_Hz)) for t in c[1]}}
             for c, sol in zip(coarse, sols)]
    points = [Point(dict(sol.kc), dict(sol.mc), np.asarray(sol.freqs_Hz), np.asarray(sol.shapes)) for sol in sols]
    # the refined meshes in a process of their own: their memory is not stacked on the diagnosis's (module doc);
    # a small mesh's in this one (ISOLATE_DOFS)
    args = (spec, tuple(halve), points, n_modes, lift is not None)
    shifts, n_fine = (isolate.call(refined_shifts, *args, what="the mesh error's refined meshes")
                      if system.n_dofs >= ISOLATE_DOFS else refined_shifts(*args))
    out = MeshErrors(tuple(halve), n_dofs=(int(system.n_dofs), n_fine))
    for per_state in shifts:
        for k, res in enumerate(per_state):
            total[k] = total[k] + res.shift
            dshape[k] = dshape[k] + res.shape_change
            floor[k] = np.maximum(floor[k], res.lost)
            fine_shares = res.shares
            if grads[k] is not None:  # d c / d coef: half the change of the energy share (module doc)
                for key, j in (("gk", 0), ("gm", 1)):
                    for t, g in grads[k][key].items():
                        if t in fine_shares[j]:
                            g += 0.5 * np.nan_to_num(fine_shares[j][t] - coarse[k][j][t])  # not followed: 0
    out.gradient = [] if any(g is None for g in grads) else grads
    for d, sol, idx, model_shift, moved, lost in zip(data, sols, index, total, dshape, floor):
        idx = np.asarray(idx, int)
        paired = model_shift[idx[idx >= 0]]  # an unpaired measured mode: the largest of the paired ones
        worst = paired[np.argmax(np.abs(paired))] if len(paired) else 0.0
        shift = np.where(idx >= 0, model_shift[np.maximum(idx, 0)], worst)
        out.model_shift.append(model_shift)
        out.shapes.append(np.asarray(sol.shapes, float))
        out.shape_shift.append(moved)
        out.shape_floor.append(lost)
        out.per_solid.append(None if solid is None else _per_solid(model_shift, solid[len(out.per_solid)]))
        out.shift.append(shift)
        out.known.append(np.abs(np.expm1(shift)))
        rel = _relative_change(moved, sol.shapes)[np.maximum(idx, 0)]
        log(f"diagnosis: mesh error of {d.name}: " + ", ".join(f"{100 * np.expm1(c):+.2f} %" for c in shift)
            + "; shapes " + ", ".join(f"{100 * v:.2f} %" if i >= 0 else "-" for v, i in zip(rel, idx)) + " of their RMS")
    log(f"diagnosis: the mesh error in {time.time() - t0:.0f} s")  # the log's, not the results' (byte-identical)
    return out


class Point(NamedTuple):
    """What the refined meshes need of one state's solution on the run's mesh: its coefficients, and its
    model modes' frequencies and probe shapes (the modes the refined ones are followed from)."""

    kc: dict
    mc: dict
    freqs_Hz: np.ndarray
    shapes: np.ndarray


def refined_shifts(spec, halve: tuple, points: list[Point], n_modes: int, shares: bool):
    """Per class of ``halve``, per state of ``points``, the :class:`ClassShift` of the state's model modes on
    the mesh with that class's cells halved; and the largest refined mesh's DOFs.  States at equal
    coefficients share one solve.  (Run in a process of its own by :func:`estimate_mesh_errors`.)"""
    from jointid.diagnosis.terms import build_system
    from jointid.fe.model import build_model
    from jointid.fe.modal import release_heap

    out, n_fine = [], 0
    for cls in halve:
        fine = build_system(build_model(spec, halve=(cls,)), spec)
        n_fine = max(n_fine, int(fine.n_dofs))
        done = []  # (coefficients, result) of the states solved
        for p in points:
            same = next((c for (kc, mc), c in done if kc == p.kc and mc == p.mc), None)
            done.append(((p.kc, p.mc), _class_shift(fine, p, n_modes, shares) if same is None else same))
        out.append([res for _, res in done])
        del fine
        release_heap()
    return out, n_fine


def _class_shift(fine, sol, n_modes: int, shares: bool = False):
    """One state's log shift of every model mode when the cells of one class are halved: the refined
    modes followed by MAC at the probe; a mode not followed takes the state's largest shift.  Returns
    ``(shift, energy shares, shape change, lost)``: with ``shares``, :func:`_shares` of the followed refined
    modes, aligned with the model modes (a mode not followed: the model's own, i.e. no change), else empty;
    the change of each followed mode's probe shape (the refined shape scaled to the model's by least
    squares, less the model's; zero where not followed); and per mode the known shape error of a mode not
    followed (the largest relative change of the followed ones; zero where followed).  A :class:`ClassShift`."""
    from jointid.correlate.pairing import pair_by_shapes
    from jointid.fe.modal import solve_modes

    modes = solve_modes(fine.K(sol.kc), fine.M(sol.mc), n_modes, fixed=fine.fixed)
    refined = fine.probe @ modes.phi
    follow, _ = pair_by_shapes(sol.shapes, refined, threshold=FOLLOW_MAC)
    follow = np.asarray(follow)
    shift = np.full(len(sol.freqs_Hz), np.nan)
    seen = np.flatnonzero(follow >= 0)
    shift[seen] = np.log(modes.freqs_Hz[follow[seen]] / sol.freqs_Hz[seen])
    ok = np.isfinite(shift)
    worst = shift[ok][np.argmax(np.abs(shift[ok]))] if ok.any() else 0.0
    moved = np.zeros(np.shape(sol.shapes))
    a, b = sol.shapes[:, seen], refined[:, follow[seen]]
    moved[:, seen] = b * (np.sum(a * b, axis=0) / np.maximum(np.sum(b * b, axis=0), 1e-300)) - a
    lost = np.where(ok, 0.0, float(np.max(_relative_change(moved[:, seen], a), initial=0.0)))
    found = ({}, {})
    if shares:
        lam = (2 * np.pi * modes.freqs_Hz[follow[seen]]) ** 2
        gk, gm = _shares(fine, modes.phi[:, follow[seen]], lam, sol)
        found = tuple({t: _aligned(v, seen, len(shift)) for t, v in g.items()} for g in (gk, gm))
    return ClassShift(np.where(ok, shift, worst), found, moved, lost)


def _per_solid(model_shift: np.ndarray, share: np.ndarray) -> float | None:
    """The median log correction per unit solids' energy share over a state's model modes (those with at
    least a tenth of their energy in the solids: a mode almost all in the springs says little)."""
    share = np.asarray(share, float)
    ok = share >= 0.1
    return float(np.median(model_shift[ok] / share[ok])) if ok.any() else None


def solid_share(solver, sol, cols=None) -> np.ndarray:
    """For the modes ``cols`` of ``sol`` (default: all), the share of their strain energy in the solids
    (:func:`jointid.fe.solids.is_solid_term`) rather than the spring layers, from the reduced solver's
    projected terms.  The Ritz vectors are mass-normalised, so a mode's whole strain energy is its
    eigenvalue and only the solids' few terms are evaluated."""
    from jointid.fe.reduced import pad_to_basis
    from jointid.fe.solids import is_solid_term

    cols = np.arange(sol.Y.shape[1]) if cols is None else np.asarray(cols, int)
    Y = pad_to_basis(sol.Y[:, cols], solver.V.shape[1])
    coef = {"K0": 1.0 + float(sol.kc.get("K0", 0.0))}
    coef.update({t: float(c) for t, c in sol.kc.items() if t != "K0" and c and is_solid_term(t) and t in solver.Kr})
    solid = sum(c * np.einsum("ij,ij->j", Y, solver.Kr[t] @ Y) for t, c in coef.items())
    return np.clip(solid / np.maximum(np.asarray(sol.lam, float)[cols], 1e-300), 0.0, 1.0)


def _aligned(values: np.ndarray, seen: np.ndarray, n: int) -> np.ndarray:
    out = np.full(n, np.nan)
    out[seen] = values
    return out


def _shares(system, phi: np.ndarray, lam: np.ndarray, sol) -> tuple[dict, dict]:
    """``d ln lambda / d coef`` of every stiffness term of ``sol.kc`` (``phi^T K_t phi / lambda``) and mass
    term of ``sol.mc`` (``-phi^T M_t phi``) for the modes ``phi`` (full space, made mass-normalised here)."""
    M = system.M(sol.mc)
    phi = phi / np.sqrt(np.maximum(np.einsum("ij,ij->j", phi, M @ phi), 1e-300))
    gk = {t: np.einsum("ij,ij->j", phi, system.stiffness[t] @ phi) / lam for t in sol.kc if t in system.stiffness}
    gm = {t: -np.einsum("ij,ij->j", phi, system.mass[t] @ phi) for t in sol.mc if t in system.mass}
    return gk, gm


def _relative_change(moved: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """Per mode, the norm of a shape change relative to the norm of the shape."""
    return np.linalg.norm(moved, axis=0) / np.maximum(np.linalg.norm(shapes, axis=0), 1e-300)


def correct(d, sol, share=None):
    """The solution ``sol`` of state ``d`` with the mesh's correction applied to its frequencies and, where
    the reference has them, its probe shapes (``sol`` itself where the state has none).  Each model mode
    takes the corrections of the modes at the point they were computed, weighted by MAC² at the probe: a
    mode that continues one of them (MAC near 1) takes its correction, two close modes that mix take a
    blend, and the correction moves continuously with the parameters (a hard match would jump when a MAC
    crosses a threshold, and the fit's objective with it).  The correction so stays with the model mode
    when close modes change order or pairing during a fit.  A shape change is carried over in the scale
    and sign of the mode it is applied to (:func:`shape_change`).

    ``share``: ``sol``'s solids' energy shares (:func:`solid_share`), or a callable giving those of the
    modes ``cols`` (``share(cols)``).  Where the reference has a correction per unit share, a mode the
    reference modes hold little of takes that times its share instead (module doc)."""
    ref = d.mesh_reference
    if ref is None:
        return sol
    from dataclasses import replace

    c = _blend(ref.shapes, sol, ref.model_shift) + drift(d, sol)
    if ref.per_solid is not None and share is not None:
        from jointid.correlate.pairing import mac

        held = np.clip(np.sum(mac(ref.shapes, sol.shapes) ** 2, axis=0) / FOLLOW_MAC ** 2, 0.0, 1.0)
        cols = np.flatnonzero(held < 1.0)
        if len(cols):
            s = share(cols) if callable(share) else np.asarray(share, float)[cols]
            c[cols] = held[cols] * c[cols] + (1.0 - held[cols]) * ref.per_solid * np.asarray(s, float)
    # a refinement only lowers a frequency, and the correction stays of its size where the first order
    # is stretched: at most twice the state's largest
    c = np.clip(c, 2.0 * min(float(np.min(ref.model_shift)), 0.0), 0.0)
    shapes = sol.shapes if ref.shape_shift is None else sol.shapes + shape_change(ref, sol.shapes)
    return replace(sol, freqs_Hz=sol.freqs_Hz * np.exp(c), shapes=shapes)


def _weights(ref_shapes: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """MAC² of the reference modes (rows) with the modes ``shapes`` (columns), each column summing to one
    (equal weights where no reference mode is like it)."""
    from jointid.correlate.pairing import mac

    w = mac(ref_shapes, shapes) ** 2  # (n_reference, n_modes)
    total = w.sum(axis=0)
    return np.where(total > 1e-12, w / np.maximum(total, 1e-12), 1.0 / max(len(w), 1))


def _blend(shapes, sol, values: np.ndarray) -> np.ndarray:
    """Per model mode of ``sol``, ``values`` of the reference modes (``shapes`` at the probe) weighted by
    MAC² (their mean where no reference mode is like it)."""
    return _weights(shapes, sol.shapes).T @ values


def shape_change(ref: MeshReference, shapes: np.ndarray) -> np.ndarray:
    """The mesh's change of the probe shapes ``shapes`` (n_labels, n): each reference mode's change
    carried to a mode in proportion to its projection on the reference mode (so in that mode's scale and
    sign), MAC²-weighted over the reference modes as :func:`correct` does."""
    proj = (ref.shapes.T @ shapes) / np.maximum(np.sum(ref.shapes ** 2, axis=0), 1e-300)[:, None]
    return ref.shape_shift @ (_weights(ref.shapes, shapes) * proj)


def shape_known(d, shapes: np.ndarray, rows: np.ndarray, mode: int) -> np.ndarray | None:
    """The known error of the probe entries ``rows`` (a mask or index) of mode ``mode`` of ``shapes``
    (n_labels, n; already corrected), relative to the mode's RMS over those entries: the size of the
    correction itself (the refined meshes' own error, at most the step they took, as for the frequencies;
    module doc), and for a mode no refined mesh could follow the largest relative change of the followed
    ones.  None where the state has no shape correction."""
    ref = d.mesh_reference
    if ref is None or ref.shape_shift is None:
        return None
    phi = shapes[:, [mode]]
    change = shape_change(ref, phi)[rows, 0]
    rms = float(np.sqrt(np.mean(phi[rows, 0] ** 2)))
    floor = 0.0 if ref.shape_floor is None else float((_weights(ref.shapes, phi).T @ ref.shape_floor)[0])
    return np.sqrt((change / max(rms, 1e-300)) ** 2 + floor ** 2)


def drift(d, sol) -> np.ndarray:
    """Per model mode of ``sol``, the first-order change of its log mesh correction since the point where
    it was computed: ``sum_t (d c / d coef_t) (coef_t - coef_t,ref)`` over the stiffness and mass terms
    (module doc), blended over the reference modes as :func:`correct` does; zeros where the state has
    no correction or no gradient."""
    ref = d.mesh_reference
    if ref is None or ref.gradient is None:
        return np.zeros(len(sol.freqs_Hz))
    g = ref.gradient
    change = np.zeros(ref.shapes.shape[1])
    for key, coef, now in (("gk", "kc", sol.kc), ("gm", "mc", sol.mc)):
        for t, grad in g[key].items():
            c0, c1 = float(g[coef].get(t, 0.0)), float(now.get(t, 0.0))
            if c1 == c0:
                continue
            change = change + grad * (c1 - c0)
    return _blend(ref.shapes, sol, change)
