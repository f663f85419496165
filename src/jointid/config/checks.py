"""Semantic checks of the configuration: what one key's schema cannot say.

Each ``check_*`` function looks at several keys of the normalised configuration (geometry fits,
bound order, DOE size, mesh size, damping fields of the chosen model ...) through a
:class:`Checks` context and adds one problem per finding.  A key that already has a schema error
is skipped (:class:`Skip`), so a problem is reported once.  The checks of the rig geometry and mesh
size are in :mod:`jointid.config.rig`, those of states and datasets in
:mod:`jointid.config.datasets`; :func:`jointid.config.load.check_config` runs them all.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from jointid.config.messages import fmt_num, need_phrase, show, suggest
from jointid.config.schema import subschema

__all__ = [
    "Checks",
    "Skip",
    "check_doe",
    "check_harmonic",
    "check_joints",
    "check_materials",
    "check_run",
    "check_solver",
]

STAGE_FOLDERS = ("carriage_rigidity", "diagnosis", "doe", "ema", "harmonic", "hypotheses", "identify", "mesh_check",
                 "modal", "model", "report", "rom", "surface", "tables")
"""The folders the stages write directly under results/ (a run name must not be one of them)."""

_POINT_RE = re.compile(r"^[TB](0[1-9]|1[0-8])$")


class Skip(Exception):
    """A semantic check lacks valid input (already reported by the schema)."""


class Checks:
    """Context for the semantic checks: the normalised config and the paths with schema errors."""

    def __init__(self, cfg: dict, bad: set[tuple], schema: Mapping):
        self.cfg = cfg
        self.bad = bad
        self.schema = schema
        self.problems: list[tuple[list, str]] = []

    def get(self, dotted: str) -> Any:
        """The value at ``dotted``; :class:`Skip` if it or a parent has a schema error or is absent."""
        parts = tuple(dotted.split("."))
        for n in range(1, len(parts) + 1):
            if parts[:n] in self.bad:
                raise Skip
        node: Any = self.cfg
        for p in parts:
            if not isinstance(node, Mapping) or p not in node:
                raise Skip
            node = node[p]
        return node

    def num(self, dotted: str) -> float:
        """The finite number at ``dotted``; :class:`Skip` otherwise."""
        value = self.get(dotted)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise Skip
        return value

    def need(self, dotted: str) -> str:
        """'the <title> in <unit>, <range>' for a key, from the schema."""
        sub: Mapping | None = self.schema
        for part in dotted.split("."):
            sub = subschema(sub or {}, part)
        return need_phrase(sub or {}, dotted.rsplit(".", 1)[-1])

    def add(self, dotted: str | list, message: str) -> None:
        """Note a problem at the key ``dotted`` (dotted text or a list of path parts)."""
        self.problems.append((dotted.split(".") if isinstance(dotted, str) else list(dotted), message))


def check_materials(c: Checks) -> None:
    """Every rig part names a material of ``materials``."""
    try:
        materials = c.get("materials")
    except Skip:
        return
    names = list(materials) if isinstance(materials, Mapping) else []
    for part in ("base", "rails", "carriages", "table"):
        try:
            name = c.get(f"rig.{part}.material")
        except Skip:
            continue
        if isinstance(name, str) and name not in names:
            guess = suggest(name, names)
            advice = f"did you mean {guess!r}?" if guess else f"use one of: {', '.join(names)} or add it to materials"
            c.add(f"rig.{part}.material", f"{name!r} is not in materials — {advice}")


_DAMPING_PARAMS = {
    "modal": ("damping_ratio",),
    "rayleigh": ("alpha_per_s", "beta_s"),
    "joint": ("joint_loss_factor_s",),
    "measured": (),
}
"""Damping fields each harmonic.damping.model needs (as in jointid.response.damping; joint_energy_share is computed)."""

_DIRECTION_OF_NAME = {"normal": "y", "lateral": "x", "feed": "z"}


def check_joints(c: Checks) -> None:
    """Identified bounds are ordered, directions match the names and are unique, nothing is both fixed and identified."""
    try:
        params = c.get("joints.parameters")
    except Skip:
        return
    if not isinstance(params, Mapping):
        return
    seen_dir: dict[str, str] = {}
    for name, p in params.items():
        base = f"joints.parameters.{name}"
        try:
            lower, upper = c.num(base + ".lower"), c.num(base + ".upper")
            if lower > upper:
                c.add(base, f"lower {fmt_num(lower)} >= upper {fmt_num(upper)} — bounds are inverted; swap them")
            elif lower == upper:
                c.add(base, f"lower {fmt_num(lower)} == upper {fmt_num(upper)} — widen the bounds, or move it to joints.fixed to keep it constant")
        except Skip:
            pass
        try:
            direction = c.get(base + ".direction")
        except Skip:
            continue
        word = name[2:-len("_N_per_m3")]
        expected = _DIRECTION_OF_NAME.get(word)
        if expected is not None and direction != expected:
            c.add(base + ".direction", f"{direction!r} contradicts the name: {word} springs act along {expected} — set direction: {expected}")
        if direction in seen_dir:
            c.add(base + ".direction", f"{direction!r} is already identified by {seen_dir[direction]} — identify each direction once; remove one or change its direction")
        else:
            seen_dir[direction] = name
    try:
        fixed = c.get("joints.fixed")
    except Skip:
        return
    if isinstance(fixed, Mapping):
        for name in fixed:
            if name in params:
                c.add(f"joints.fixed.{name}", "is also in joints.parameters — a stiffness is either identified or fixed; remove it from one of them")


def _n_identified(c: Checks) -> int:
    params = c.get("joints.parameters")
    if not isinstance(params, Mapping) or not params:
        raise Skip
    return len(params)


def check_doe(c: Checks) -> None:
    """The design has enough distinct points for the quadratic response surface."""
    try:
        k = _n_identified(c)
        design = c.get("doe.design")
    except Skip:
        return
    n_coef = (k + 1) * (k + 2) // 2
    try:
        if design == "lhs":
            n = c.num("doe.n_samples")
            if n < 2 * n_coef:
                c.add("doe.n_samples", f"{n} is too few for lhs: a quadratic surface in {k} parameter{'s' if k > 1 else ''} has {n_coef} coefficients — use n_samples >= {2 * n_coef} (twice that) or design: ccf")
        elif design == "box_behnken":
            if k < 3:
                c.add("doe.design", f"box_behnken needs at least 3 identified parameters, joints.parameters has {k} — use design: ccf")
            elif c.num("doe.n_center") < 1:
                c.add("doe.n_center", "0 with design box_behnken leaves the quadratic surface undetermined — use n_center >= 1")
        elif design == "ccf":
            distinct = (2**k + 2 * k if k > 1 else 2) + min(1, c.num("doe.n_center"))
            if distinct < n_coef:
                c.add("doe.n_center", f"0 with design ccf and {k} parameter gives only {distinct} distinct points for {n_coef} coefficients — use n_center >= 1")
    except Skip:
        pass


def check_harmonic(c: Checks) -> None:
    """Band order, drive point name, and the damping fields of the chosen damping model."""
    try:
        band = c.get("harmonic.band_Hz")
        if isinstance(band, list) and len(band) == 2 and all(
            isinstance(b, (int, float)) and not isinstance(b, bool) for b in band
        ):
            if band[0] >= band[1]:
                c.add("harmonic.band_Hz", f"{show(band)} is not increasing — write [low, high]")
    except Skip:
        pass
    try:
        point = c.get("harmonic.drive_point")
        if isinstance(point, str) and not _POINT_RE.match(point):  # normally caught by the schema
            c.add("harmonic.drive_point", f"{point!r} is not a measuring-point name — use T01..T18 (table) or B01..B18 (base)")
    except Skip:
        pass
    try:
        model = c.get("harmonic.damping.model")
        damping = c.get("harmonic.damping")
    except Skip:
        return
    if model not in _DAMPING_PARAMS or not isinstance(damping, Mapping):
        return
    for key in _DAMPING_PARAMS[model]:
        if key not in damping:
            c.add(f"harmonic.damping.{key}", f"missing for model {model!r} — add {key}: {c.need(f'harmonic.damping.{key}')}")
    for key in damping:
        owner = next((m for m, keys in _DAMPING_PARAMS.items() if key in keys), None)
        if owner is not None and owner != model:
            c.add(f"harmonic.damping.{key}",
                  f"is set but model is {model!r} — remove it, or set model: {owner}; to switch the model in a "
                  f"config file merged after the one that sets it, write {key}: null there")


def check_solver(c: Checks) -> None:
    """A free rig is not factorised at zero shift; not all mode weights are zero."""
    try:
        if c.get("rig.support.kind") == "free" and c.num("solver.shift_Hz") == 0:
            c.add("solver.shift_Hz", "0 with rig.support.kind: free factorises a singular stiffness (rigid-body modes) — use a negative shift, e.g. -10")
    except Skip:
        pass
    try:
        weights = c.get("identify.weights")
        if isinstance(weights, list) and weights and all(
            isinstance(w, (int, float)) and not isinstance(w, bool) and w == 0 for w in weights
        ):
            c.add("identify.weights", "all weights are 0 — give at least one positive weight, or [] for all 1")
    except Skip:
        pass


def check_run(c: Checks) -> None:
    """A run name is not the folder of a stage (results/<name>/ would mix the study with the default's)."""
    try:
        name = c.get("run.name")
    except Skip:
        return
    if name in STAGE_FOLDERS:
        c.add("run.name", f"{name!r} is the folder of a stage under results/ — choose another name, e.g. "
                          f"{name}_study")


def check_model(c: Checks) -> None:
    """``model.kind: mesh``: the mesh and point files exist, bodies name materials, joint laws name
    known parameters and every identified parameter acts on a layer, and nothing asks to refine the
    user's mesh."""
    from pathlib import Path

    try:
        if c.get("model.kind") != "mesh":
            return
        model = c.get("model")
    except Skip:
        return
    for key, what in (("path", "the mesh file (gmsh .msh, Abaqus .inp, .vtu)"),
                      ("points", "the measuring points CSV (point, x_m, y_m, z_m)")):
        value = model.get(key, "")
        if not value:
            c.add(f"model.{key}", f"missing — model.kind: mesh needs {what}")
        elif not Path(value).is_file():
            c.add(f"model.{key}", f"{value}: no such file (paths are relative to the working directory) — give {what}")
    if not model.get("bodies"):
        c.add("model.bodies", "empty — name each solid group of the mesh with its material, e.g. {frame: steel}")
    materials = c.cfg.get("materials") or {}
    for name, material in (model.get("bodies") or {}).items():
        if material not in materials:
            c.add(f"model.bodies.{name}", f"{material!r} is not in materials — use one of: {', '.join(materials)} or add it")
    joints = c.cfg.get("joints") or {}
    known = set(joints.get("parameters") or {}) | set(joints.get("fixed") or {})
    used = set()
    for i, joint in enumerate(model.get("joints") or []):
        for comp, value in (joint.get("law") or {}).items():
            if isinstance(value, str):
                used.add(value)
                if value not in known:
                    c.add(f"model.joints[{i}].law.{comp}", f"{value!r} is neither in joints.parameters nor in joints.fixed "
                          f"— use one of {sorted(known)} or give a stiffness per area in N/m^3")
    for name in sorted(set(joints.get("parameters") or {}) - used):
        c.add(f"joints.parameters.{name}", "no layer of model.joints uses it, so it cannot be identified — "
              "name it in a joint's law, or remove it")
    if (c.cfg.get("mesh") or {}).get("extrapolate_edges"):
        c.add("mesh.extrapolate_edges", "true refines the parametric rig's edges; a mesh file is solved as it is — "
              "set mesh.extrapolate_edges: false (refine in the tool that made the mesh)")
