"""(g) Where the mesh error of the lateral modes sits: grid lines added beside one set of part edges.

The lateral (sway, yaw) modes converge slowest under mesh refinement.  This benchmark adds a pair of
grid lines ``offset`` either side of one set of part boundaries at a time (so that only the cells
touching those edges shrink), solves at the identified power-off parameters
(``results/identify/power_off/params.json``; the middle of the bounds without it), pairs the modes
with the default mesh's by MAC at the measuring points and prints how far each edge set moves the
two modes that move most (and every other mode at most).  The edge sets: the base top (rail foot),
the rail top (the block's inner corner above the rail), the carriage top (block-to-table junction),
the rail and block sides along X, the block ends along Z, and all of them together.

Then the cure: local refinement at the re-entrant edges (``mesh.edge_refine_levels`` 1 to 4, cells
halved across the edges only, hanging nodes tied) — each level's frequency change against the default
mesh and, with the default run's ``verify.csv`` present, the first-order change of the identified
parameters that a re-identification on that mesh would give (the mesh check's formula).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from .common import COARSE, ROOT, Result
from jointid.config.typed import ModelSpec

OFFSET_M = 0.003


def edge_sets(rig) -> dict[str, dict[int, list[float]]]:
    """Coordinates of the part boundaries per axis (0 X, 1 Y, 2 Z), grouped by the edge they form."""
    d = rig.dims
    cx = sorted({round(c, 9) for b in rig.boxes if b.part in ("rail", "carriage") for c in (b.lo[0], b.hi[0])})
    cz = sorted({round(c, 9) for b in rig.boxes if b.part == "carriage" for c in (b.lo[2], b.hi[2])})
    sets = {"base top (rail foot)": {1: [d["base_top_m"]]},
            "rail top (block inner corner)": {1: [d["rail_top_m"]]},
            "carriage top (block-to-table)": {1: [d["carriage_top_m"]]},
            "rail and block sides (X)": {0: cx},
            "block ends (Z)": {2: cz}}
    every: dict[int, list[float]] = {}
    for s in sets.values():
        for ax, cs in s.items():
            every.setdefault(ax, []).extend(cs)
    sets["all of them"] = every
    return sets


def with_lines(rig, coords: dict[int, list[float]], offset: float):
    """``rig`` with extra breakpoints ``c - offset`` and ``c + offset`` (inside the grid) per axis."""
    bps = list(rig.breakpoints)
    for ax, cs in coords.items():
        add = np.array([c + s * offset for c in cs for s in (-1, 1)])
        add = add[(add > bps[ax].min()) & (add < bps[ax].max())]
        bps[ax] = np.unique(np.round(np.concatenate([bps[ax], add]), 9))
    return replace(rig, breakpoints=tuple(bps))


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    from jointid.config import load_config
    from jointid.fe.model import build_model, joint_terms
    from jointid.geometry.rig import build_rig
    from jointid.identification.polish import solve_point
    from jointid.identification.polish import log_jacobian

    res = Result("g")
    cfg = load_config(ROOT / "config.yaml", overrides=COARSE if quick else None)
    names = list(cfg["joints"]["parameters"])
    path = ROOT / "results" / "identify" / "power_off" / "params.json"
    if path.exists():
        theta = {n: v["value"] for n, v in json.loads(path.read_text())["parameters"].items()}
    else:
        theta = {n: float(np.sqrt(p["lower"] * p["upper"])) for n, p in cfg["joints"]["parameters"].items()}
        res.notes.append(f"{path.relative_to(ROOT)} missing: solved at the middle of the bounds")
    theta = {n: theta[n] for n in names}
    n_modes = 14
    rig = build_rig(cfg["rig"])
    ref = build_model(ModelSpec.from_config(cfg), rig=rig)
    f0, s0, _, modes0 = solve_point(ModelSpec.from_config(cfg), ref, theta, n_modes=n_modes, describe=False)
    n0 = ref.n_dofs
    jt = joint_terms(ModelSpec.from_config(cfg).joints)
    J = log_jacobian(ref.stiffness, modes0.phi, modes0.omega2, [{t: 1.0 for t in jt[n]} for n in names],
                     np.array([theta[n] for n in names]))  # d ln f / d log10 theta on the default mesh
    del ref, modes0
    data = {"theta": theta, "offset_m": OFFSET_M, "n_dofs_default": n0, "freqs_default_Hz": f0.tolist(),
            "sets": {}}
    track = f0 > cfg["solver"]["min_freq_Hz"]
    for label, coords in edge_sets(rig).items():
        model = build_model(ModelSpec.from_config(cfg), rig=with_lines(rig, coords, OFFSET_M))
        f, s, _, _ = solve_point(ModelSpec.from_config(cfg), model, theta, n_modes=n_modes, describe=False)
        index, macs, ok, change, order = _change(f0, s0, track, f, s)
        top2, rest = order[:2], order[2:]
        res.add(f"{label}: +{model.n_dofs - n0:,} DOFs",
                ", ".join(f"{f0[i]:.0f} Hz {change[i]:+.2f} %" for i in top2)
                + f"; others >= {np.nanmin(change[rest]):+.2f} %")
        data["sets"][label] = {"n_dofs": model.n_dofs, "change_pct": change.tolist(), "mac": macs.tolist()}
        print(f"[g] {label}: {model.n_dofs} DOFs, " + ", ".join(f"{c:+.2f}" for c in change), flush=True)
        del model
    _edge_levels(res, cfg, theta, J, f0, s0, track, n0, data, quick)
    res.notes.append(f"grid lines {1e3 * OFFSET_M:g} mm either side of each edge set; default mesh {n0:,} DOFs; "
                     "modes paired by MAC at the measuring points; frequency change vs the default mesh")
    res.data = data
    return res


def _change(f0, s0, track, f, s):
    """Modes of a refined mesh paired with the default mesh's by MAC: ``(index, macs, ok, change %,
    modes ordered by change)``."""
    from jointid.correlate.pairing import pair_by_shapes

    index, macs = pair_by_shapes(s0, s, threshold=0.8)
    ok = track & (index >= 0)
    change = np.full(len(f0), np.nan)
    change[ok] = 100 * (f[index[ok]] / f0[ok] - 1)
    return index, macs, ok, change, np.argsort(np.nan_to_num(change, nan=0.0))


def _edge_levels(res: Result, cfg, theta, J, f0, s0, track, n0, data, quick):
    """Local refinement at the re-entrant edges, 1 to 4 levels (1 to 2 with ``quick``)."""
    import pandas as pd

    from jointid.identification.meshcheck import first_order_shift
    from jointid.fe.model import build_model
    from jointid.identification.polish import solve_point

    names = list(theta)
    verify = ROOT / "results" / "identify" / "power_off" / "verify.csv"
    # the default run's pairing (measured mode -> model mode) holds for the default mesh only
    fe_mode = pd.read_csv(verify)["fe_mode"].to_numpy(int) - 1 if verify.exists() and not quick else None
    if fe_mode is None:
        res.notes.append("no parameter changes for the edge levels (needs the default run's "
                         f"{verify.relative_to(ROOT)}, full mesh)")
    data["edge_levels"] = {}
    for levels in range(1, 3 if quick else 5):
        c = json.loads(json.dumps(cfg))
        c["mesh"]["edge_refine_levels"] = levels
        model = build_model(ModelSpec.from_config(c))
        f, s, _, _ = solve_point(ModelSpec.from_config(c), model, theta, n_modes=len(f0), describe=False)
        index, macs, ok, change, order = _change(f0, s0, track, f, s)
        text = ", ".join(f"{f0[i]:.0f} Hz {change[i]:+.2f} %" for i in order[:2])
        entry = {"n_dofs": model.n_dofs, "change_pct": change.tolist(), "mac": macs.tolist()}
        if fe_mode is not None:
            rows = fe_mode[(fe_mode >= 0) & ok[np.clip(fe_mode, 0, None)]]
            delta = first_order_shift(J[rows], np.log(f[index[rows]] / f0[rows]))
            entry["parameter_change_pct"] = dict(zip(names, (100 * (10 ** delta - 1)).tolist()))
            text += "; " + ", ".join(f"{n.split('_')[1]} {v:+.1f} %" for n, v in entry["parameter_change_pct"].items())
        res.add(f"edge_refine_levels {levels}: +{model.n_dofs - n0:,} DOFs", text)
        data["edge_levels"][levels] = entry
        print(f"[g] edge levels {levels}: {model.n_dofs} DOFs, {text}", flush=True)
        del model
