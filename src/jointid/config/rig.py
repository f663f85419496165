"""Semantic checks of the rig: its parts fit together, and the mesh they make is not too large.

The geometry checks compare dimensions of different parts (rails on the base, carriages under the
table, mount pads inside the base ...); the mesh check estimates the FE node count
(:func:`estimate_node_count`) before any mesh is built and names the smallest cell size that
passes.  Both run through the :class:`~jointid.config.checks.Checks` context.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping

from jointid.config.checks import Checks, Skip
from jointid.config.messages import fmt_num

__all__ = ["MAX_NODES", "check_geometry", "check_mesh", "estimate_node_count"]

MAX_NODES = 2_000_000
"""Largest estimated FE node count accepted by the semantic mesh check."""

_RIG = "rig."


def _rails_on_base(c: Checks) -> None:
    rl, bl = c.num(_RIG + "rails.length_m"), c.num(_RIG + "base.length_m")
    if rl > bl:
        c.add(_RIG + "rails.length_m", f"{fmt_num(rl)} is longer than the base ({fmt_num(bl)} m) — shorten the rails or lengthen the base")


def _rails_across_base(c: Checks) -> None:
    s, rw, bw = c.num(_RIG + "rails.spacing_m"), c.num(_RIG + "rails.width_m"), c.num(_RIG + "base.width_m")
    if s + rw > bw:
        c.add(_RIG + "rails.spacing_m", f"spacing {fmt_num(s)} + rail width {fmt_num(rw)} = {fmt_num(s + rw)} exceeds the base width {fmt_num(bw)} — the rails must stand on the base; reduce spacing_m or widen the base")


def _carriages_apart_across(c: Checks) -> None:
    s, cw = c.num(_RIG + "rails.spacing_m"), c.num(_RIG + "carriages.width_m")
    if s < cw:
        c.add(_RIG + "rails.spacing_m", f"{fmt_num(s)} is less than the carriage width {fmt_num(cw)} — carriages on the two rails would overlap; use spacing_m >= carriages.width_m")


def _carriages_apart_along(c: Checks) -> None:
    p, cl = c.num(_RIG + "carriages.pitch_m"), c.num(_RIG + "carriages.length_m")
    if p < cl:
        c.add(_RIG + "carriages.pitch_m", f"{fmt_num(p)} is less than the carriage length {fmt_num(cl)} — the two carriages on a rail would overlap; use pitch_m >= carriages.length_m")


def _carriages_under_table_along(c: Checks) -> None:
    p, cl, tl = c.num(_RIG + "carriages.pitch_m"), c.num(_RIG + "carriages.length_m"), c.num(_RIG + "table.length_m")
    if p + cl > tl:
        c.add(_RIG + "carriages.pitch_m", f"pitch {fmt_num(p)} + carriage length {fmt_num(cl)} = {fmt_num(p + cl)} exceeds the table length {fmt_num(tl)} — the carriages must fit under the table; reduce pitch_m or lengthen the table")


def _carriages_under_table_across(c: Checks) -> None:
    s, cw, tw = c.num(_RIG + "rails.spacing_m"), c.num(_RIG + "carriages.width_m"), c.num(_RIG + "table.width_m")
    if s + cw > tw:
        c.add(_RIG + "rails.spacing_m", f"spacing {fmt_num(s)} + carriage width {fmt_num(cw)} = {fmt_num(s + cw)} exceeds the table width {fmt_num(tw)} — the carriages must fit under the table; reduce spacing_m or widen the table")


def _table_on_rails(c: Checks) -> None:
    pos, p, cl, rl = (c.num(_RIG + "table.position_m"), c.num(_RIG + "carriages.pitch_m"),
                      c.num(_RIG + "carriages.length_m"), c.num(_RIG + "rails.length_m"))
    half_span = (p + cl) / 2
    limit = rl / 2 - half_span
    if abs(pos) > limit + 1e-12:
        if limit < 0:
            c.add(_RIG + "table.position_m", f"the carriage span {fmt_num(p + cl)} is longer than the rails ({fmt_num(rl)}) — lengthen the rails or reduce carriages.pitch_m")
        else:
            c.add(_RIG + "table.position_m", f"{fmt_num(pos)} moves the carriages off the rails — keep |position_m| <= {fmt_num(round(limit, 9))} (half rail length minus half the carriage span)")


def _carriage_wraps_rail(c: Checks) -> None:
    cw, rw = c.num(_RIG + "carriages.width_m"), c.num(_RIG + "rails.width_m")
    flanks = c.get("joints.lateral_face") == "flanks"
    if cw < rw or (flanks and cw == rw):
        c.add(_RIG + "carriages.width_m", f"{fmt_num(cw)} is not wider than the rail ({fmt_num(rw)}) — the carriage wraps the rail and must cover its top{' and flanks' if flanks else ''}; widen the carriage")


def _flank_contact_fits(c: Checks) -> None:
    if c.get("joints.lateral_face") != "flanks":
        return
    fh, gc, rh = (c.num(_RIG + "carriages.flank_contact_height_m"), c.num(_RIG + "carriages.ground_clearance_m"),
                  c.num(_RIG + "rails.height_m"))
    if fh + gc > rh:
        c.add(_RIG + "carriages.flank_contact_height_m", f"flank contact {fmt_num(fh)} + ground clearance {fmt_num(gc)} = {fmt_num(fh + gc)} exceeds the rail height {fmt_num(rh)} — the contact band must lie on the rail flank; reduce one of them")


def _carriage_above_rail(c: Checks) -> None:
    ch, rh = c.num(_RIG + "carriages.height_m"), c.num(_RIG + "rails.height_m")
    if ch <= rh:
        c.add(_RIG + "carriages.height_m", f"{fmt_num(ch)} does not reach above the rail top ({fmt_num(rh)} above the base) — carriage height is measured from the base top; make it larger than rails.height_m")


def _clearance_below_rail_top(c: Checks) -> None:
    gc, rh = c.num(_RIG + "carriages.ground_clearance_m"), c.num(_RIG + "rails.height_m")
    if gc >= rh:
        c.add(_RIG + "carriages.ground_clearance_m", f"{fmt_num(gc)} is not below the rail height {fmt_num(rh)} — the carriage's lower edge must lie beside the rail; reduce ground_clearance_m")


def _motor_patch_on_table(c: Checks) -> None:
    for dim, tkey in (("patch_width_m", "width_m"), ("patch_length_m", "length_m")):
        pv, tv = c.num(_RIG + "motors." + dim), c.num(_RIG + "table." + tkey)
        if pv > tv:
            c.add(_RIG + "motors." + dim, f"{fmt_num(pv)} exceeds the table {tkey[:-2]} {fmt_num(tv)} — the motor mass is spread under the table; use {dim} <= table.{tkey}")


def _mounts_fit(c: Checks) -> None:
    if c.get(_RIG + "support.kind") != "mounts":
        return
    inset, size = c.num(_RIG + "support.mount_inset_m"), c.num(_RIG + "support.mount_size_m")
    half = min(c.num(_RIG + "base.length_m"), c.num(_RIG + "base.width_m")) / 2
    if inset < size / 2:
        c.add(_RIG + "support.mount_inset_m", f"{fmt_num(inset)} is less than half the mount size ({fmt_num(size / 2)}) — the inset is measured to the mount centre, so the pads would stick out of the base; use mount_inset_m >= mount_size_m / 2")
    elif inset + size / 2 > half:
        c.add(_RIG + "support.mount_inset_m", f"inset {fmt_num(inset)} + half the mount size {fmt_num(size / 2)} = {fmt_num(inset + size / 2)} exceeds half the smaller base side ({fmt_num(half)}) — the four mount pads would overlap; reduce mount_inset_m or mount_size_m")


_GEOMETRY_CHECKS = (_rails_on_base, _rails_across_base, _carriages_apart_across, _carriages_apart_along,
                    _carriages_under_table_along, _carriages_under_table_across, _table_on_rails,
                    _carriage_wraps_rail, _flank_contact_fits, _carriage_above_rail,
                    _clearance_below_rail_top, _motor_patch_on_table, _mounts_fit)
"""The geometry checks, in the order their problems are reported."""


MAX_RIG_LENGTH_M = 5.0
"""A rig dimension or position above this (in m) is not a feed drive's: the value was given in mm."""


def _lengths_in_metres(c: Checks) -> None:
    """Every ``rig.*_m`` value is a plausible length in m; one that looks like mm is reported with the
    value in m, and its key is marked bad so that the fit and mesh-size checks skip it."""
    try:
        rig = c.get("rig")
    except Skip:
        return

    def walk(node, path):
        if isinstance(node, Mapping):
            for k, v in node.items():
                walk(v, path + [str(k)])
        elif (path[-1].endswith("_m") and not path[-1].endswith("_per_m") and isinstance(node, (int, float))
              and not isinstance(node, bool)):
            if math.isfinite(node) and abs(node) > MAX_RIG_LENGTH_M and tuple(path) not in c.bad:
                c.add(path, f"{fmt_num(node)} m is not a plausible size of a machine-tool feed drive; the value "
                      f"looks like mm — write {fmt_num(node / 1000)} (the unit of every *_m key is m)")
                c.bad.add(tuple(path))

    walk(rig, ["rig"])


def check_geometry(c: Checks) -> None:
    """The values are lengths in m, and the parts of the rig fit together: rails on the base, carriages
    under the table, mounts ..."""
    _lengths_in_metres(c)
    for check in _GEOMETRY_CHECKS:
        try:
            check(c)
        except Skip:
            pass


def _part_boxes(rig: Mapping) -> list[tuple[float, float, float]]:
    """(X, Y, Z) extents in m of the meshed parts: base, 2 rails, 4 carriages, table."""
    b, r, k, t = rig["base"], rig["rails"], rig["carriages"], rig["table"]
    return ([(b["width_m"], b["height_m"], b["length_m"])]
            + 2 * [(r["width_m"], r["height_m"], r["length_m"])]
            + 4 * [(k["width_m"], k["height_m"], k["length_m"])]
            + [(t["width_m"], t["thickness_m"], t["length_m"])])


def estimate_node_count(cfg: Mapping) -> int:
    """Lower-bound estimate of the FE node count of the mesh configured in ``cfg``.

    Each part is counted as its own box gridded with cells of edge at most
    ``mesh.max_cell_size_m / mesh.refine`` (times ``mesh.height_cell_fraction`` along Y; at least one
    cell per direction); hex2 has
    ``2 n + 1`` and hex1 ``n + 1`` nodes per direction.  Interface lines added by other parts
    only make the real mesh larger, so this never over-estimates much.

    Parameters
    ----------
    cfg : mapping
        Normalised configuration (``rig`` and ``mesh`` sections).

    Returns
    -------
    int
        Estimated number of nodes.
    """
    mesh = cfg["mesh"]
    h = mesh["max_cell_size_m"] / mesh["refine"]
    hs = (h, h * mesh.get("height_cell_fraction", 1.0), h)
    per = 2 if mesh["element"] == "hex2" else 1
    total = 0
    for box in _part_boxes(cfg["rig"]):
        nodes = 1
        for extent, he in zip(box, hs):
            nodes *= per * max(1, math.ceil(extent / he - 1e-9)) + 1
        total += nodes
    return total


def check_mesh(c: Checks) -> None:
    """The estimated node count stays within :data:`MAX_NODES`; else the cell size that passes."""
    try:
        for key in ("mesh.max_cell_size_m", "mesh.refine"):
            c.num(key)
        c.get("mesh.element")
        for part, keys in (("base", ("length_m", "width_m", "height_m")),
                           ("rails", ("length_m", "width_m", "height_m")),
                           ("carriages", ("length_m", "width_m", "height_m")),
                           ("table", ("length_m", "width_m", "thickness_m"))):
            for key in keys:
                c.num(f"rig.{part}.{key}")
    except Skip:
        return
    n = estimate_node_count(c.cfg)
    if n <= MAX_NODES:
        return
    # smallest cell size (2 significant digits, rounded up) that passes
    lo, hi = c.cfg["mesh"]["max_cell_size_m"], max(_part_boxes(c.cfg["rig"])[0]) * c.cfg["mesh"]["refine"]
    probe = copy.deepcopy(c.cfg)
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        probe["mesh"]["max_cell_size_m"] = mid
        if estimate_node_count(probe) > MAX_NODES:
            lo = mid
        else:
            hi = mid
    exp = math.floor(math.log10(hi)) - 1
    good = math.ceil(hi / 10**exp) * 10**exp
    h = c.cfg["mesh"]["max_cell_size_m"]
    refine = c.cfg["mesh"]["refine"]
    c.add("mesh.max_cell_size_m",
          f"{fmt_num(h)} is too small (with refine: {refine}): about {fmt_num(float(f'{n:.2g}'))} nodes, "
          f"above the limit of {fmt_num(float(MAX_NODES))}"
          f" — use max_cell_size_m >= {fmt_num(float(f'{good:.2g}'))} with refine: {refine}")
