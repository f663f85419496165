"""Parametric geometry of the linear-motor feed-drive stage (the paper's test rig, reconstructed).

The rig is a set of axis-aligned boxes, so one tensor grid whose lines pass through every part
boundary meshes all of it.  Parts and the two bodies they form:

* body 0: the ``base`` plate;
* body 1 (bonded): four ``carriage`` blocks that wrap the rails and the ``table`` on top of them;
* body 2: the two ``rail`` s, fixed to the base through a stiff spring layer on their bottom faces
  (bonded, the paper's "consolidation", unless the rail-fixing compliance is of interest).

The carriages meet the rails only at the contact faces, where the joint springs act:
``top`` (rail top under each carriage: normal, Y) and ``flank`` (upper strip of each rail side under
each carriage: lateral, X).  Axes: X lateral, Y up, Z feed; origin at the base's bottom centre.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

PART_IDS = {"void": -1, "base": 0, "rail": 1, "carriage": 2, "table": 3}
BODY_OF_PART = {0: 0, 1: 2, 2: 1, 3: 1}  # base | carriages + table | rails
BONDED_GROUP_OF_PART = {0: 0, 1: 0, 2: 1, 3: 1}  # base + rails (stiff fixing layer) | carriages + table


def body_of(part: np.ndarray) -> np.ndarray:
    """Body of each part id (``BODY_OF_PART``); -1 (void) stays -1."""
    part = np.asarray(part)
    return np.where(part >= 0, np.array([BODY_OF_PART[i] for i in range(len(BODY_OF_PART))])[np.maximum(part, 0)], -1)


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``[lo, hi]`` in metres, tagged with a part name."""

    part: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def contains(self, pts: np.ndarray) -> np.ndarray:
        """Boolean mask of points ``(n, 3)`` strictly inside the box."""
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        return np.all((pts > lo) & (pts < hi), axis=1)


@dataclass(frozen=True)
class Rig:
    """Geometry of the stage: part boxes (in priority order), contact regions and named patches.

    All lengths in m.  ``contact`` maps a joint face name (``top``, ``flank``) to a list of boxes that are
    degenerate (zero thickness) along the face normal; ``patches`` maps names (``motor``, ``mount``) to
    degenerate boxes of surface regions.
    """

    boxes: list[Box]
    contact: dict[str, list[Box]]
    patches: dict[str, list[Box]]
    carriage_centres: np.ndarray  # (4, 3) centre of each carriage's rail-top contact face
    breakpoints: tuple[np.ndarray, np.ndarray, np.ndarray]
    materials: dict[str, str]  # part -> material name
    dims: dict[str, float] = field(default_factory=dict)
    joint_zone: tuple[list, list, list] = ([], [], [])  # per axis: (lo, hi) intervals around the joints

    def part_at(self, pts: np.ndarray) -> np.ndarray:
        """Part id (see ``PART_IDS``) of each point ``(n, 3)``; the first box in the list wins."""
        ids = np.full(len(pts), -1, dtype=int)
        for box in self.boxes:
            free = ids < 0
            hit = free & box.contains(pts)
            ids[hit] = PART_IDS[box.part]
        return ids


def build_rig(geometry: Mapping) -> Rig:
    """Build the stage geometry from the rig's description (the ``rig`` section of the configuration:
    :attr:`jointid.config.typed.RigModel.geometry`)."""
    b, r, c, t = geometry["base"], geometry["rails"], geometry["carriages"], geometry["table"]
    mot, sup = geometry["motors"], geometry["support"]
    H, rail_top = b["height_m"], b["height_m"] + r["height_m"]
    c_top = b["height_m"] + c["height_m"]
    t_top = c_top + t["thickness_m"]
    zt = t["position_m"]
    half_s = r["spacing_m"] / 2
    boxes: list[Box] = []
    xs: set[float] = set()
    ys: set[float] = {0.0, H, rail_top, c_top, t_top, H + c["ground_clearance_m"],
                      rail_top - c["flank_contact_height_m"]}
    zs: set[float] = set()

    def add(part, lo, hi):
        boxes.append(Box(part, tuple(lo), tuple(hi)))
        xs.update((lo[0], hi[0]))
        zs.update((lo[2], hi[2]))

    # priority order: rails before carriages (a carriage wraps the rail: rail cells stay rail)
    for sx in (-1, 1):
        xc = sx * half_s
        add("rail", (xc - r["width_m"] / 2, H, -r["length_m"] / 2),
            (xc + r["width_m"] / 2, rail_top, r["length_m"] / 2))
    centres = []
    top_faces, flank_faces = [], []
    for sx in (-1, 1):
        xc = sx * half_s
        for sz in (-1, 1):
            zc = zt + sz * c["pitch_m"] / 2
            z0, z1 = zc - c["length_m"] / 2, zc + c["length_m"] / 2
            add("carriage", (xc - c["width_m"] / 2, H + c["ground_clearance_m"], z0),
                (xc + c["width_m"] / 2, c_top, z1))
            centres.append((xc, rail_top, zc))
            xr0, xr1 = xc - r["width_m"] / 2, xc + r["width_m"] / 2
            top_faces.append(Box("top", (xr0, rail_top, z0), (xr1, rail_top, z1)))
            yf0 = rail_top - c["flank_contact_height_m"]
            flank_faces.append(Box("flank", (xr0, yf0, z0), (xr0, rail_top, z1)))
            flank_faces.append(Box("flank", (xr1, yf0, z0), (xr1, rail_top, z1)))
    add("table", (-t["width_m"] / 2, c_top, zt - t["length_m"] / 2),
        (t["width_m"] / 2, t_top, zt + t["length_m"] / 2))
    add("base", (-b["width_m"] / 2, 0.0, -b["length_m"] / 2), (b["width_m"] / 2, H, b["length_m"] / 2))

    pw, pl = mot["patch_width_m"] / 2, mot["patch_length_m"] / 2
    motor = [Box("motor", (-pw, c_top, zt - pl), (pw, c_top, zt + pl))]
    xs.update((-pw, pw))
    zs.update((zt - pl, zt + pl))
    mounts = []
    if sup["kind"] == "mounts":
        a = sup["mount_size_m"] / 2
        for sx in (-1, 1):
            for sz in (-1, 1):
                xm = sx * (b["width_m"] / 2 - sup["mount_inset_m"])
                zm = sz * (b["length_m"] / 2 - sup["mount_inset_m"])
                mounts.append(Box("mount", (xm - a, 0.0, zm - a), (xm + a, 0.0, zm + a)))
                xs.update((xm - a, xm + a))
                zs.update((zm - a, zm + a))
    railfix = [Box("railfix", (sx * half_s - r["width_m"] / 2, H, -r["length_m"] / 2),
                   (sx * half_s + r["width_m"] / 2, H, r["length_m"] / 2)) for sx in (-1, 1)]
    edge = [Box("edge", (t["width_m"] / 2, c_top, zt - t["length_m"] / 2),
                (t["width_m"] / 2, t_top, zt + t["length_m"] / 2))]
    top = [Box("table_top", (-t["width_m"] / 2, t_top, zt - t["length_m"] / 2),
               (t["width_m"] / 2, t_top, zt + t["length_m"] / 2))]
    materials = {"base": b["material"], "rail": r["material"], "carriage": c["material"],
                 "table": t["material"]}
    dims = {"base_top_m": H, "rail_top_m": rail_top, "carriage_top_m": c_top, "table_top_m": t_top,
            "table_z_m": zt}
    # the joint zone: the carriage footprints (X, Z) from the base top to the carriage top (Y), where the
    # contact strips load the rail and carriage locally and a finer grid is needed to converge
    zone_x = [(sx * half_s - c["width_m"] / 2, sx * half_s + c["width_m"] / 2) for sx in (-1, 1)]
    zone_z = [(zt + sz * c["pitch_m"] / 2 - c["length_m"] / 2, zt + sz * c["pitch_m"] / 2 + c["length_m"] / 2)
              for sz in (-1, 1)]
    zone_y = [(H, c_top)]
    return Rig(boxes=boxes, contact={"top": top_faces, "flank": flank_faces},
               patches={"motor": motor, "mount": mounts, "railfix": railfix, "table_edge": edge,
                        "table_top": top}, carriage_centres=np.array(centres),
               breakpoints=(np.array(sorted(xs)), np.array(sorted(ys)), np.array(sorted(zs))),
               materials=materials, dims=dims, joint_zone=(zone_x, zone_y, zone_z))


def grid_lines(breakpoints: np.ndarray, max_cell_m: float, refine: int = 1,
               zones: list[tuple[float, float]] = (), zone_cell_m: float | None = None,
               zone_refine: int = 1) -> np.ndarray:
    """Subdivide sorted breakpoints so that no cell is longer than ``max_cell_m / refine``.

    Intervals lying inside one of ``zones`` (``(lo, hi)`` in m) use ``zone_cell_m`` instead of
    ``max_cell_m`` (when given and smaller) and are divided ``max(refine, zone_refine)`` times as
    finely.  Breakpoints closer than 1e-9 m are merged.  Every interval is divided into equal cells,
    so the grid for ``refine = 2`` contains every line of the grid for ``refine = 1`` (nested
    meshes).  Returns the sorted grid coordinates.
    """
    bp = np.unique(np.round(np.asarray(breakpoints, float), 9))
    out = [bp[:1]]
    for a, b in zip(bp[:-1], bp[1:]):
        h = max_cell_m
        split = int(refine)
        if any(lo - 1e-9 <= a and b <= hi + 1e-9 for lo, hi in zones):
            if zone_cell_m is not None:
                h = min(h, zone_cell_m)
            split = max(split, int(zone_refine))
        n = max(1, int(np.ceil((b - a) / h - 1e-9))) * split
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)
