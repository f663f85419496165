"""Import modal test data from Universal File Format (UFF/UNV) files into a dataset folder.

Supported datasets (read with pyuff):

* 164 -- units.  Its length factor sets the coordinate unit; length and force factors scale FRFs.
* 15, 2411 -- nodes (id, x, y, z).
* 55 -- mode shapes: normal modes (analysis type 2: frequency, viscous damping ratio) or complex
  modes (types 3 and 7: eigenvalue ``lambda`` in rad/s, ``f = |lambda| / 2 pi``,
  ``zeta = -Re(lambda) / |lambda|``).  Node values r1, r2, r3 are the x, y, z components.
  They are copied without scaling, because shapes are compared independently of scale.
  Complex shapes are rotated to their best real direction, and the real part is kept.
* 58 -- FRFs (function type 4).  Displacement, velocity or acceleration over force are
  converted to receptance in m/N.  The response node becomes ``point`` and the reference node
  becomes ``frf_drive_point``.

UFF nodes are mapped to measuring points as follows.  An explicit ``node_map`` entry wins.
Otherwise a node id matches a point if exactly one point name ends in that number
(``7`` -> ``T07`` when no ``B07`` exists).  Failing that, the nearest point within ``tol_m``
is used.  Coordinates are scaled to metres by dataset 164 when the file has one, else by
``length_scale`` (default 1.0, i.e. metres).  Unmatched nodes and points are listed in the
report.

CLI::

    python -m jointid.data.uff IN.unv --state power_off --points results/model/measuring_points.csv \\
        --out data/mytest [--tol-m 0.005] [--length-scale 0.001] [--em-force-N 0] [--merge]
        [--node-map nodes.csv] [--modes-from-frf N] [--frequencies-only]

Frequencies of datasets 55 and 58 are in Hz by the format's definition: the dataset written says
``frequencies_in_Hz_confirmed: true`` (no kHz guess).  A file whose every shape is dropped (no node
matched a measuring point) is an error unless ``--frequencies-only``; unmatched nodes are summed up
in one line with the matching rule.  Complex and 6-DOF shapes are reported as made real / reduced
to translations.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

from jointid.errors import DataError
from jointid.data.dataset import Dataset, read_dataset, write_dataset
from jointid.data.validate import DIRECTIONS

_FRF_KIND = {8: "displacement", 11: "velocity", 12: "acceleration"}


def _read_sets(path: Path) -> list[dict]:
    import pyuff  # noqa: PLC0415  (import on use: pyuff is only needed here)

    if not path.is_file():
        raise DataError(f"{path}: UFF file does not exist — check the path")
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exception
        raise DataError(f"{path}: cannot read as a Universal File ({exc}) — export it as ASCII "
                        "UFF (datasets 15/2411, 55, 58)") from exc
    return [sets] if isinstance(sets, dict) else list(sets)


def _units(sets, length_scale, report):
    """Return ``(length_to_m, force_to_N)`` multipliers."""
    units = [s for s in sets if s.get("type") == 164]
    if units:
        u = units[0]
        to_m, to_n = 1.0 / float(u["length"]), 1.0 / float(u["force"])
        if length_scale is not None and not np.isclose(length_scale, to_m):
            report.append(f"length_scale = {length_scale:g} ignored: the file's units dataset 164 "
                          f"says 1 unit = {to_m:g} m")
        return to_m, to_n
    return (1.0 if length_scale is None else float(length_scale)), 1.0


def _suffix_index(names) -> dict[int, list[str]]:
    index: dict[int, list[str]] = {}
    for name in names:
        m = re.search(r"(\d+)$", name)
        if m:
            index.setdefault(int(m.group(1)), []).append(name)
    return index


def map_nodes(nodes: pd.DataFrame, measuring_points: pd.DataFrame, *, tol_m=0.005,
              node_map=None) -> tuple[dict[int, str], list[str]]:
    """Map UFF node ids to measuring-point names.

    Parameters
    ----------
    nodes : DataFrame
        Columns ``node`` (int) and ``x_m, y_m, z_m`` (NaN if the node has no coordinates).
    measuring_points : DataFrame
        Columns ``point, x_m, y_m, z_m``.
    tol_m : float
        Largest distance in m for a coordinate match.
    node_map : dict, optional
        Explicit ``{node_id: point}`` entries, which take precedence.

    Returns
    -------
    mapping : dict
        ``{node_id: point}``.
    report : list of str
        One line per unmatched node, unmatched point, conflict or doubtful match.
    """
    report: list[str] = []
    names = [str(p) for p in measuring_points["point"]]
    xyz = measuring_points[["x_m", "y_m", "z_m"]].to_numpy(float)
    by_suffix = _suffix_index(names)
    node_map = {int(k): str(v) for k, v in (node_map or {}).items()}
    candidates: dict[str, list[tuple[float, int]]] = {}
    for node, x, y, z in nodes[["node", "x_m", "y_m", "z_m"]].itertuples(index=False):
        node = int(node)
        has_xyz = np.all(np.isfinite([x, y, z]))
        dist = np.linalg.norm(xyz - [x, y, z], axis=1) if has_xyz else None
        if node in node_map:
            point = node_map[node]
            if point not in names:
                report.append(f"UFF node {node}: node_map names {point!r}, which is not a "
                              "measuring point; node left unmatched")
                continue
            how = "node_map"
        elif len(by_suffix.get(node, [])) == 1:
            point, how = by_suffix[node][0], "name"
        elif has_xyz and dist.min() <= tol_m:
            point, how = names[int(np.argmin(dist))], "coordinates"
        else:
            if has_xyz:
                near = int(np.argmin(dist))
                report.append(f"UFF node {node} not matched: nearest point {names[near]} is "
                              f"{dist[near]:.4g} m away (tol_m = {tol_m:g})")
            else:
                report.append(f"UFF node {node} not matched: no coordinates and no point name "
                              "ending in that number")
            continue
        gap = dist[names.index(point)] if has_xyz else 0.0
        if how != "coordinates" and gap > tol_m:
            report.append(f"UFF node {node} mapped to {point} by {how} although it is {gap:.4g} m "
                          "from that point; check the numbering")
        candidates.setdefault(point, []).append((gap, node))
    mapping = {}
    for point, cands in candidates.items():
        cands.sort()
        mapping[cands[0][1]] = point
        for _, node in cands[1:]:
            report.append(f"UFF node {node} not matched: point {point} is already taken by the "
                          f"closer node {cands[0][1]}")
    for point in names:
        if point not in mapping.values():
            report.append(f"measuring point {point} not matched by any UFF node")
    return mapping, report


def _nodes_table(sets, to_m) -> pd.DataFrame:
    rows = {}
    for s in sets:
        if s.get("type") in (15, 2411):
            for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"]):
                rows[int(n)] = (x * to_m, y * to_m, z * to_m)
    for s in sets:  # nodes referenced without coordinates
        ids = list(s.get("node_nums", [])) if s.get("type") == 55 else []
        if s.get("type") == 58:
            ids = [s.get("rsp_node"), s.get("ref_node")]
        for n in ids:
            if n is not None:
                rows.setdefault(int(n), (np.nan, np.nan, np.nan))
    return pd.DataFrame([(n, *xyz) for n, xyz in sorted(rows.items())],
                        columns=["node", "x_m", "y_m", "z_m"])


def uff_points(path, *, length_scale: float | None = None) -> pd.DataFrame:
    """Measuring points from the node datasets (15 or 2411) of a Universal File: columns ``point``
    (the node number), ``x_m, y_m, z_m`` (m, by the file's units dataset 164 or ``length_scale``)."""
    sets = _read_sets(Path(path))
    to_m, _ = _units(sets, length_scale, [])
    nodes = _nodes_table(sets, to_m).dropna()
    if nodes.empty:
        raise DataError(f"{path}: no node coordinates (datasets 15 or 2411) — export the test geometry with the file")
    return pd.DataFrame({"point": nodes["node"].astype(str), "x_m": nodes["x_m"], "y_m": nodes["y_m"],
                         "z_m": nodes["z_m"]})


def _realise(values: np.ndarray) -> tuple[np.ndarray, float]:
    """Rotate a complex shape to its best real direction; return (real shape, real-energy share)."""
    if not np.iscomplexobj(values):
        return values.astype(float), 1.0
    theta = 0.5 * np.angle(np.sum(values**2))
    rotated = values * np.exp(-1j * theta)
    total = np.sum(np.abs(values) ** 2)
    return rotated.real, float(np.sum(rotated.real**2) / total) if total else 1.0


def _modes(sets, mapping, report):
    modes, shapes = [], []
    six_dof_said = False
    for k, s in enumerate(s for s in sets if s.get("type") == 55):
        atype = s.get("analysis_type")
        if atype == 2:
            freq = float(s["freq"])
            zeta = float(s.get("modal_damp_vis", 0.0))
            if zeta == 0.0 and float(s.get("modal_damp_his", 0.0)) > 0:
                zeta = 0.5 * float(s["modal_damp_his"])
                report.append(f"UFF 55 mode {s.get('mode_n')}: damping from the hysteretic ratio "
                              "(zeta = eta / 2)")
        elif atype in (3, 7):
            lam = complex(s["eig"])
            freq, zeta = abs(lam) / (2 * np.pi), -lam.real / abs(lam)
        else:
            report.append(f"UFF 55 set {k + 1}: analysis type {atype} is not a mode; skipped")
            continue
        if s.get("data_ch") not in (2, 3):
            report.append(f"UFF 55 mode {s.get('mode_n')}: data characteristic {s.get('data_ch')} "
                          "has no x, y, z components; skipped")
            continue
        if s.get("data_ch") == 3 and not six_dof_said:
            report.append("UFF 55: 6-DOF shapes (data characteristic 3): the translations r1, r2, r3 are "
                          "kept, the rotations r4, r5, r6 dropped")
            six_dof_said = True
        raw = np.concatenate([np.asarray(s[k]) for k in ("r1", "r2", "r3")])
        stacked, share = _realise(raw)
        if np.iscomplexobj(raw):
            report.append(f"UFF 55 mode {s.get('mode_n')}: complex shape made real (rotated to its best real "
                          f"direction, real part kept: {100 * share:.0f} % of its energy)")
        n = len(s["node_nums"])
        values = stacked.reshape(3, n)
        modes.append((freq, zeta, s.get("mode_n"), len(modes)))
        for j, node in enumerate(s["node_nums"]):
            if int(node) in mapping:
                for i, d in enumerate(DIRECTIONS):
                    shapes.append((len(modes) - 1, mapping[int(node)], d, float(values[i, j])))
    modes.sort()
    renumber = {idx: m + 1 for m, (_, _, _, idx) in enumerate(modes)}
    if any(orig is not None and int(orig) != renumber[idx] for _, _, orig, idx in modes):
        report.append("UFF 55 mode numbers were renumbered 1..n in order of frequency")
    return modes, [(renumber[idx], p, d, v) for idx, p, d, v in shapes]


def _frfs(sets, mapping, to_m, to_n, report):
    frf_sets = []
    for s in (s for s in sets if s.get("type") == 58):
        label = f"UFF 58 {s.get('id1', '').strip() or s.get('rsp_node')}"
        if s.get("func_type") != 4:
            report.append(f"{label}: function type {s.get('func_type')} is not an FRF; skipped")
            continue
        rdir, node = int(s.get("rsp_dir", 0)), int(s.get("rsp_node", -1))
        if abs(rdir) not in (1, 2, 3):
            report.append(f"{label}: response direction {rdir} is not a translation; skipped")
            continue
        if node not in mapping:
            report.append(f"{label}: response node {node} is not a measuring point; skipped")
            continue
        frf_sets.append((s, label, mapping[node], DIRECTIONS[abs(rdir) - 1], np.sign(rdir)))
    if not frf_sets:
        return [], None
    drives = Counter((int(s.get("ref_node", -1)), int(s.get("ref_dir", 0))) for s, *_ in frf_sets)
    (ref_node, ref_dir), _ = drives.most_common(1)[0]
    if ref_node not in mapping or abs(ref_dir) not in (1, 2, 3):
        report.append(f"UFF 58: drive node {ref_node} direction {ref_dir} is not a measuring-point "
                      "translation; all FRFs skipped")
        return [], None
    rows = []
    for s, label, point, direction, sign in frf_sets:
        if (int(s.get("ref_node", -1)), int(s.get("ref_dir", 0))) != (ref_node, ref_dir):
            report.append(f"{label}: drive node {s.get('ref_node')} differs from the main drive "
                          f"node {ref_node}; skipped")
            continue
        f = np.asarray(s["x"], float)
        h = np.asarray(s["data"]) * sign * np.sign(ref_dir) * to_m / to_n
        kind = _FRF_KIND.get(s.get("ordinate_spec_data_type"))
        keep = f > 0
        if not keep.all():
            report.append(f"{label}: {np.count_nonzero(~keep)} line(s) at 0 Hz dropped")
        f, h, w = f[keep], h[keep], 2 * np.pi * f[keep]
        if kind == "velocity":
            h = h / (1j * w)
        elif kind == "acceleration":
            h = h / -(w**2)
        elif kind is None:
            report.append(f"{label}: ordinate type {s.get('ordinate_spec_data_type')} unknown; "
                          "assumed displacement/force (receptance)")
        rows += [(point, direction, fi, hi.real, hi.imag) for fi, hi in zip(f, h)]
    return rows, (mapping[ref_node], DIRECTIONS[abs(ref_dir) - 1])


def condense_mapping_report(lines: list[str], tol_m: float, shown: int = 3) -> list[str]:
    """The node-mapping lines with the unmatched nodes and points summed up: up to ``shown`` each
    are listed, the rest counted in one line that states the matching rule and how to map them."""
    nodes = [ln for ln in lines if ln.startswith("UFF node ") and " not matched" in ln]
    points = [ln for ln in lines if ln.startswith("measuring point ")]
    rest = [ln for ln in lines if ln not in nodes and ln not in points]
    out = rest + nodes[:shown]
    if len(nodes) > shown:
        out.append(f"... {len(nodes)} UFF nodes not matched in all (rule: a --node-map entry, else the one point "
                   f"name ending in the node's number, else the nearest point within tol_m = {tol_m:g} m); map "
                   "them with --node-map CSV (columns node,point)")
    if points:
        names = [ln.split()[2] for ln in points]
        more = f" and {len(names) - 8} more" if len(names) > 8 else ""
        out.append(f"{len(names)} measuring point(s) have no UFF node: {', '.join(names[:8])}{more}")
    return out


def _frf_modes(frf_rows: list, n_modes: int, report: list) -> list:
    """Modes picked from the summed FRF magnitude (:func:`modes_from_frf`) as ``_modes`` records."""
    df = pd.DataFrame(frf_rows, columns=["point", "direction", "freq_Hz", "re", "im"])
    grid = np.unique(df["freq_Hz"].to_numpy(float))
    H = np.zeros((len(grid), 0))
    for _, g in df.groupby(["point", "direction"], sort=False):
        h = np.interp(grid, g["freq_Hz"].to_numpy(float), np.hypot(g["re"], g["im"]).to_numpy(float))
        H = np.column_stack([H, h])
    picked = modes_from_frf(grid, H, n_modes)
    report.append(f"{len(picked)} modes picked from {H.shape[1]} FRF(s) by peak picking with half-power "
                  "damping (no shapes)")
    return [(float(f), float(z) if np.isfinite(z) else 0.0, i + 1, i)
            for i, (f, z) in enumerate(zip(picked["freq_Hz"], picked["damping_ratio"]))]


def import_uff(path, measuring_points: pd.DataFrame, *, state: str, tol_m: float = 0.005,
               out=None, length_scale: float | None = None, node_map: dict | None = None,
               em_force_N: float | None = None, merge: bool = False, n_frf_modes: int | None = None,
               frequencies_only: bool = False) -> tuple[Dataset, list[str]]:
    # many parameters: the import's options (node mapping, tolerance, scale, merge, ...), keyword with defaults
    # long by its numpydoc; the body is one pass (units, nodes, modes, FRFs, conditions, write)
    """Import one state's modal test data from a UFF file.

    Parameters
    ----------
    path : path
        ASCII Universal File.
    measuring_points : DataFrame
        Columns ``point, x_m, y_m, z_m`` (m, model axes: X lateral, Y vertical, Z feed).
    state : str
        State name for every imported row (e.g. ``power_off``).
    tol_m : float
        Coordinate-matching tolerance in m.
    out : path, optional
        Dataset folder to write (atomically; see :func:`jointid.data.dataset.write_dataset`).
    length_scale : float, optional
        Metres per file length unit (0.001 for mm).  Used only when the file has no dataset 164.
    node_map : dict, optional
        Explicit ``{uff_node_id: point_name}``.
    em_force_N : float, optional
        Vertical motor force of this state in N.  If omitted, 0.0 is written and the report
        says so.
    merge : bool
        With ``out``: keep the other states of an existing dataset there and replace ``state``.
    n_frf_modes : int, optional
        For a file with FRFs (dataset 58) but no modes: pick this many modes from the summed FRF
        magnitude (:func:`modes_from_frf`; frequencies and half-power damping, no shapes).
    frequencies_only : bool
        Import the modes although every shape was dropped (no node matched a measuring point);
        otherwise that is an error.

    Returns
    -------
    dataset : Dataset
        Modes (``freq_Hz``, ``damping_ratio`` when every mode has one), shapes at mapped points,
        FRFs (receptance in m/N).
    report : list of str
        Node mapping, unit and skipped-data lines.
    """
    path = Path(path)
    sets = _read_sets(path)
    report: list[str] = []
    to_m, to_n = _units(sets, length_scale, report)
    nodes = _nodes_table(sets, to_m)
    mapping, map_report = map_nodes(nodes, measuring_points, tol_m=tol_m, node_map=node_map)
    report += condense_mapping_report(map_report, tol_m)
    if length_scale is None and to_m == 1.0 and nodes["x_m"].notna().any():
        alt, _ = map_nodes(nodes.assign(**{c: nodes[c] * 1e-3 for c in ("x_m", "y_m", "z_m")}),
                           measuring_points, tol_m=tol_m, node_map=node_map)
        if len(alt) > len(mapping):
            report.append("coordinates look like mm (more nodes match when scaled by 0.001); "
                          "pass length_scale=0.001 (--length-scale 0.001)")
    modes, shapes = _modes(sets, mapping, report)
    frf_rows, drive = _frfs(sets, mapping, to_m, to_n, report)
    if not modes and frf_rows and n_frf_modes:
        modes = _frf_modes(frf_rows, n_frf_modes, report)
    if not modes:
        has58 = any(s.get("type") == 58 for s in sets)
        hint = (" — the file has FRFs (dataset 58): pick the modes from them with --modes-from-frf N "
                "(n_frf_modes=N)" if has58 and frf_rows else
                " — export the modal model with mode shapes (dataset 55), or FRFs (dataset 58, function type 4)")
        raise DataError([f"{path}: no mode shapes (dataset 55) found{hint}"] + report)
    n55 = sum(1 for s in sets if s.get("type") == 55)
    if n55 and not shapes and not frequencies_only:
        raise DataError([f"{path}: every mode shape was dropped: no UFF node matched a measuring point "
                         "(see the lines below) — map the nodes with --node-map CSV (node,point), fix "
                         "--tol-m / --length-scale, or import the frequencies alone with --frequencies-only"]
                        + report)
    zetas = np.array([z for _, z, _, _ in modes])
    mode_df = pd.DataFrame({"state": state, "mode": np.arange(1, len(modes) + 1),
                            "freq_Hz": [f for f, *_ in modes]})
    if np.all(zetas > 0):
        mode_df["damping_ratio"] = zetas
    elif np.any(zetas > 0):
        report.append("some modes have no damping; damping_ratio column left out")
    shape_df = pd.DataFrame(shapes, columns=["mode", "point", "direction", "value"])
    shape_df.insert(0, "state", state)
    frf_df = None
    if frf_rows:
        frf_df = pd.DataFrame(frf_rows, columns=["point", "direction", "freq_Hz", "re", "im"])
        frf_df.insert(0, "state", state)
    cond = {"em_force_N": 0.0 if em_force_N is None else float(em_force_N)}
    if em_force_N is None:
        report.append(f"em_force_N of state {state} not given; 0.0 written — edit conditions.yaml "
                      "or pass --em-force-N")
    if drive is not None:
        cond["frf_drive_point"], cond["frf_drive_direction"] = drive
    conditions = {"source": f"UFF import of {path.name} (jointid.data.uff), state {state}",
                  "frequencies_in_Hz_confirmed": True,  # UFF 55 and 58 give frequencies in Hz by definition
                  "states": {state: cond}}
    shapes_out = shape_df if len(shape_df) else None
    if out is not None:
        if merge and Path(out).exists():
            mode_df, shapes_out, frf_df, conditions = _merge(
                read_dataset(out), state, mode_df, shapes_out, frf_df, conditions)
        dataset = write_dataset(out, mode_df, shapes_out, frf_df, conditions=conditions,
                                measuring_points=measuring_points)
    else:
        dataset = Dataset(name=path.stem, modes=mode_df, shapes=shapes_out, frf=frf_df,
                          conditions=conditions, states=[state])
    return dataset, report


def _merge(old: Dataset, state, modes, shapes, frf, conditions):
    def combine(a, b):
        parts = [t for t in ((None if a is None else a[a["state"] != state]), b) if t is not None]
        parts = [t for t in parts if len(t)]
        return pd.concat(parts, ignore_index=True) if parts else None

    if "damping_ratio" in old.modes.columns and "damping_ratio" not in modes.columns:
        old_modes = old.modes.drop(columns="damping_ratio")
    elif "damping_ratio" not in old.modes.columns and "damping_ratio" in modes.columns:
        old_modes, modes = old.modes, modes.drop(columns="damping_ratio")
    else:
        old_modes = old.modes
    merged = dict(old.conditions)
    merged["states"] = {**old.conditions["states"], state: conditions["states"][state]}
    merged["source"] = f"{old.conditions['source']}; {conditions['source']}"
    return combine(old_modes, modes), combine(old.shapes, shapes), combine(old.frf, frf), merged


def modes_from_frf(freq_Hz, H, n_modes: int) -> pd.DataFrame:
    """Peak picking with half-power damping.

    Parameters
    ----------
    freq_Hz : array, shape ``(n_freq,)``
        Increasing frequencies in Hz.
    H : array, shape ``(n_freq,)`` or ``(n_freq, n_channels)``
        FRFs (any type); channels are combined by summing ``|H|``.
    n_modes : int
        Number of peaks to keep (the most prominent ones).

    Returns
    -------
    DataFrame
        ``mode, freq_Hz, damping_ratio`` in order of frequency.  ``freq_Hz`` is the peak of
        ``|H|`` refined by a parabola through three lines (for a receptance this is
        ``f_n sqrt(1 - 2 zeta^2)``).  ``damping_ratio = (f2 - f1) / (2 f_peak)`` from the
        half-power points ``|H| = peak / sqrt(2)``, interpolated linearly.  It is NaN where a
        half-power point lies outside the band.
    """
    from scipy.signal import find_peaks  # noqa: PLC0415

    f = np.asarray(freq_Hz, float)
    mag = np.abs(np.asarray(H))
    mag = mag.sum(axis=1) if mag.ndim == 2 else mag
    peaks, props = find_peaks(mag, prominence=0)
    keep = peaks[np.argsort(props["prominences"])[::-1][:n_modes]]
    rows = []
    for p in np.sort(keep):
        fp = f[p]
        if 0 < p < len(f) - 1:
            a, b, c = mag[p - 1], mag[p], mag[p + 1]
            denom = a - 2 * b + c
            shift = 0.5 * (a - c) / denom if denom else 0.0
            fp = f[p] + shift * (f[p + 1] - f[p - 1]) / 2
        half = mag[p] / np.sqrt(2)
        lo = np.nonzero(mag[:p] < half)[0]
        hi = np.nonzero(mag[p:] < half)[0]
        zeta = np.nan
        if len(lo) and len(hi):
            i, j = lo[-1], p + hi[0]
            f1 = np.interp(half, [mag[i], mag[i + 1]], [f[i], f[i + 1]])
            f2 = np.interp(half, [mag[j], mag[j - 1]], [f[j], f[j - 1]])
            zeta = (f2 - f1) / (2 * fp)
        rows.append((fp, zeta))
    return pd.DataFrame({"mode": np.arange(1, len(rows) + 1),
                         "freq_Hz": [r[0] for r in rows], "damping_ratio": [r[1] for r in rows]})


def main(argv=None) -> int:
    """Command line: import a UFF file into a dataset folder; returns the exit code."""
    ap = argparse.ArgumentParser(prog="python -m jointid.data.uff", description=__doc__.split("\n")[0])
    ap.add_argument("uff", help="ASCII Universal File (.unv/.uff)")
    ap.add_argument("--state", required=True, help="state name, e.g. power_off")
    ap.add_argument("--points", required=True, help="measuring_points.csv (point,x_m,y_m,z_m)")
    ap.add_argument("--out", required=True, help="dataset folder to write")
    ap.add_argument("--tol-m", type=float, default=0.005, help="coordinate match tolerance (m)")
    ap.add_argument("--length-scale", type=float, default=None,
                    help="metres per file length unit when the file has no dataset 164")
    ap.add_argument("--em-force-N", type=float, default=None, help="vertical motor force (N)")
    ap.add_argument("--merge", action="store_true", help="keep other states already in --out")
    ap.add_argument("--node-map", help="CSV with columns node,point: explicit UFF node -> measuring point")
    ap.add_argument("--modes-from-frf", type=int, default=None, metavar="N",
                    help="a file with FRFs but no modes: pick N modes from the FRFs (no shapes)")
    ap.add_argument("--frequencies-only", action="store_true",
                    help="import the modes although no node matched a measuring point (shapes dropped)")
    args = ap.parse_args(argv)
    for name, f in (("measuring-points", args.points), ("node-map", args.node_map)):
        if f and not Path(f).is_file():
            where = (" — the mesh rule writes it (snakemake -j2 results/model/measuring_points.csv)"
                     if name == "measuring-points" else " — give a CSV with columns node,point")
            print(f"{f}: {name} file not found{where}", file=sys.stderr)
            return 2
    try:
        points = pd.read_csv(args.points)
        node_map = None
        if args.node_map:
            nm = pd.read_csv(args.node_map)
            if not {"node", "point"} <= set(nm.columns):
                raise DataError(f"{args.node_map}: needs the columns node,point (found {', '.join(nm.columns)})")
            node_map = dict(zip(nm["node"].astype(int), nm["point"].astype(str)))
        dataset, report = import_uff(args.uff, points, state=args.state, tol_m=args.tol_m,
                                     out=args.out, length_scale=args.length_scale, node_map=node_map,
                                     em_force_N=args.em_force_N, merge=args.merge,
                                     n_frf_modes=args.modes_from_frf, frequencies_only=args.frequencies_only)
    except (DataError, OSError) as exc:
        print(exc, file=sys.stderr)
        return 2
    for line in report:
        print(line, file=sys.stderr)
    print(f"{args.out}: {len(dataset.modes)} modes, states {', '.join(dataset.states)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
