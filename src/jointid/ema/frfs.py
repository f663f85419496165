"""Measured FRFs for the EMA: one :class:`FrfSet` per state, read from frf.csv, UFF 58 or a dataset folder.

Every FRF needs its reference (where the hammer struck): a ``reference`` column ``<point>:<direction>`` in
the CSV, the state's ``frf_drive_point``/``frf_drive_direction`` in a dataset folder's conditions.yaml,
or the reference node and direction of UFF 58.  Values become receptance in m/N.  The frequency lines
must be finite, increasing, the same for every FRF of a state, and evenly spaced from a multiple of the
spacing (LSCF works on such a grid).  Every problem is one line ``where: what — how to fix``, raised
together as one :class:`~jointid.errors.DataError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from jointid.data.validate import DIRECTIONS, Problems
from jointid.errors import DataError

__all__ = ["FrfSet", "read_frf_csv", "read_frf_uff", "read_frf_folder", "check_grid"]

_KIND = {8: 0, 11: 1, 12: 2}  # UFF ordinate type -> powers of (i w) to divide by: displacement, velocity, acceleration
CSV_COLUMNS = ("state", "point", "direction", "freq_Hz", "re", "im")


@dataclass(frozen=True)
class FrfSet:
    """The FRFs of one state on one frequency grid.

    Attributes
    ----------
    state : str
    freq_Hz : ndarray, shape (n_f,)
        Evenly spaced, increasing, > 0.
    H : ndarray of complex, shape (n_rows, n_f)
        Receptance in m/N, one row per (reference, response DOF).
    rows : DataFrame
        ``point, direction, ref_point, ref_direction`` of each row of ``H``.
    source : str
        Where the FRFs came from (file name).
    exp_decay_per_s : float
        Decay rate (1/s) an exponential response window added to every pole (time data); the EMA
        subtracts it from each pole's real part.  0 for FRFs given as such.
    coherence : ndarray, shape (n_rows, n_f), or None
        Coherence of H1 FRFs made from time data.
    """

    state: str
    freq_Hz: np.ndarray
    H: np.ndarray
    rows: pd.DataFrame
    source: str
    exp_decay_per_s: float = 0.0
    coherence: np.ndarray | None = None

    @property
    def references(self) -> list[str]:
        """The references ``<point>:<direction>`` in order of first appearance."""
        labels = self.rows["ref_point"] + ":" + self.rows["ref_direction"]
        return list(dict.fromkeys(labels))

    def drive_rows(self) -> list[int]:
        """Rows whose response is their reference (driving points)."""
        r = self.rows
        return list(np.flatnonzero((r["point"] == r["ref_point"]) & (r["direction"] == r["ref_direction"])))


def check_grid(freq: np.ndarray, where: str, problems: Problems) -> bool:
    """Whether ``freq`` is finite, > 0, increasing and evenly spaced from a multiple of its spacing."""
    if freq.size < 8:
        problems.add(where, f"only {freq.size} frequency lines", "give the FRF over its band, hundreds of lines")
        return False
    if not np.all(np.isfinite(freq)):
        problems.add(where, "a frequency is NaN or infinite", "fix or delete that line")
        return False
    step = np.diff(freq)
    if np.any(step <= 0):
        k = int(np.flatnonzero(step <= 0)[0])
        problems.add(where, f"frequencies are not increasing ({freq[k]:g} Hz then {freq[k + 1]:g} Hz)",
                     "sort the lines by frequency and keep one line per frequency")
        return False
    df = float(np.median(step))
    if np.max(np.abs(step - df)) > 1e-3 * df:
        problems.add(where, f"frequency lines are not evenly spaced (steps {step.min():g} to {step.max():g} Hz)",
                     "export the FRF on its measured grid (one spacing), without gaps")
        return False
    if freq[0] <= 0:
        problems.add(where, f"first frequency {freq[0]:g} Hz is not positive", "drop the 0 Hz line")
        return False
    if abs(freq[0] / df - round(freq[0] / df)) > 1e-3:
        problems.add(where, f"first frequency {freq[0]:g} Hz is no multiple of the spacing {df:g} Hz",
                     "export the FRF on its measured grid (lines at k times the spacing)")
        return False
    return True


def _label(point, direction) -> str:
    return f"{point}:{direction}"


def _assemble(groups: dict, state: str, source: str, problems: Problems, **extra) -> FrfSet | None:
    """One FrfSet from ``{(point, dir, ref_point, ref_dir): (where, freq, h)}``; None (problems added)."""
    ok, grid = True, None
    for key, (where, freq, h) in groups.items():
        if not np.all(np.isfinite(h)):
            problems.add(where, f"FRF {_label(*key[:2])} (reference {_label(*key[2:])}) has NaN or infinite "
                         "values", "re-export it, or delete the FRF")
            ok = False
        if not check_grid(freq, where, problems):
            ok = False
            continue
        if grid is None:
            grid = freq
        elif freq.shape != grid.shape or not np.allclose(freq, grid, rtol=1e-9, atol=0.0):
            problems.add(where, f"FRF {_label(*key[:2])} has other frequency lines than the first FRF of state "
                         f"{state}", "export every FRF of a state on the same grid")
            ok = False
    if not ok or grid is None:
        return None
    rows = pd.DataFrame([k for k in groups], columns=["point", "direction", "ref_point", "ref_direction"])
    H = np.vstack([h for _, _, h in groups.values()])
    return FrfSet(state=state, freq_Hz=np.asarray(grid, float), H=H, rows=rows, source=source, **extra)


def read_frf_csv(path, *, references: dict[str, str] | None = None) -> dict[str, FrfSet]:
    """FRFs of a CSV ``state,point,direction,freq_Hz,re,im[,reference]`` (receptance, m/N).

    ``reference`` holds ``<point>:<direction>`` per line; without the column, ``references`` gives one per
    state (a dataset folder's drive points).  A line without a reference is an error.
    """
    path = Path(path)
    problems = Problems()
    try:
        df = pd.read_csv(path, dtype={"state": str, "point": str, "direction": str, "reference": str})
    except (OSError, pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise DataError(f"{path}: cannot read as CSV ({exc}) — save it as comma-separated UTF-8") from exc
    missing = [c for c in CSV_COLUMNS if c not in df.columns]
    if missing:
        raise DataError(f"{path}:1: missing column(s) {', '.join(missing)} — the columns are "
                        f"{','.join(CSV_COLUMNS)}[,reference]")
    if "reference" not in df.columns:
        refs = references or {}
        df["reference"] = df["state"].map(lambda s: refs.get(s, ""))
    df["reference"] = df["reference"].fillna("").astype(str).str.strip()
    df["direction"] = df["direction"].astype(str).str.strip().str.lower()
    for col in ("freq_Hz", "re", "im"):
        df[col] = pd.to_numeric(df[col], errors="coerce")
    df["_line"] = np.arange(len(df)) + 2
    no_ref = df[~df["reference"].str.match(r"^[^:]+:[xyz]$")]
    for state, g in no_ref.groupby("state", sort=False):
        problems.add(f"{path}:{int(g['_line'].iloc[0])}", f"{len(g)} FRF line(s) of state {state} have no reference "
                     f"(got {g['reference'].iloc[0]!r})", "add a column reference with '<point>:<direction>' of the "
                     "hammer, e.g. T05:y (or frf_drive_point/frf_drive_direction in conditions.yaml)")
    bad_dir = df[~df["direction"].isin(DIRECTIONS)]
    if len(bad_dir):
        problems.add(f"{path}:{int(bad_dir['_line'].iloc[0])}", f"direction {bad_dir['direction'].iloc[0]!r} is not "
                     "x, y or z", "use x (lateral), y (vertical) or z (feed)")
    if problems:
        raise DataError(problems.condensed())
    out = {}
    for state, sg in df.groupby("state", sort=False):
        groups = {}
        for (point, direction, ref), g in sg.groupby(["point", "direction", "reference"], sort=False):
            rp, rd = ref.split(":")
            where = f"{path}:{int(g['_line'].iloc[0])}"
            h = g["re"].to_numpy(float) + 1j * g["im"].to_numpy(float)
            groups[(point, direction, rp, rd)] = (where, g["freq_Hz"].to_numpy(float), h)
        fs = _assemble(groups, str(state), path.name, problems)
        if fs is not None:
            out[str(state)] = fs
    if problems:
        raise DataError(problems.condensed())
    return out


def read_frf_folder(folder) -> tuple[dict[str, FrfSet], dict]:
    """FRFs of a dataset folder (frf.csv, references from conditions.yaml) and its conditions mapping."""
    folder = Path(folder)
    cond_path = folder / "conditions.yaml"
    if not (folder / "frf.csv").is_file():
        raise DataError(f"{folder}: no frf.csv — put the measured FRFs in frf.csv (docs/measurement-format.md)")
    conditions = {}
    if cond_path.is_file():
        try:
            conditions = yaml.safe_load(cond_path.read_text(encoding="utf-8")) or {}
        except yaml.YAMLError as exc:
            raise DataError(f"{cond_path}: YAML syntax error ({exc}) — fix the file") from exc
    refs = {}
    for state, c in (conditions.get("states") or {}).items():
        if isinstance(c, dict) and c.get("frf_drive_point") and c.get("frf_drive_direction"):
            refs[str(state)] = f"{c['frf_drive_point']}:{c['frf_drive_direction']}"
    return read_frf_csv(folder / "frf.csv", references=refs), conditions


def _uff_units(sets) -> tuple[float, float]:
    units = [s for s in sets if s.get("type") == 164]
    if units:
        return 1.0 / float(units[0]["length"]), 1.0 / float(units[0]["force"])
    return 1.0, 1.0


def _node_names(sets, frfs, to_m, node_map, measuring_points, tol_m) -> dict[int, str]:
    """``{node: point name}`` of every node an FRF names (see :func:`read_frf_uff`)."""
    ids = sorted({int(s[k]) for s in frfs for k in ("rsp_node", "ref_node")})
    if measuring_points is None:
        return {n: str((node_map or {}).get(n, n)) for n in ids}
    from jointid.data.uff import map_nodes  # noqa: PLC0415  (the importer's node rule)

    xyz = {int(n): (x * to_m, y * to_m, z * to_m) for s in sets if s.get("type") in (15, 2411)
           for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"])}
    nodes = pd.DataFrame([(n, *xyz.get(n, (np.nan, np.nan, np.nan))) for n in ids], columns=["node", "x_m", "y_m", "z_m"])
    mapping, _ = map_nodes(nodes, measuring_points, tol_m=tol_m, node_map=node_map)
    return mapping


def read_frf_uff(path, *, state: str = "measured", node_map: dict | None = None, measuring_points=None,
                 tol_m: float = 0.005) -> dict[str, FrfSet]:
    # many parameters: the file, the state name, and how nodes become points (map, the model's points, tolerance)
    """FRFs (UFF 58, function type 4) of a Universal File as one state.  Acceleration and velocity over force
    become receptance.  Point names: with ``measuring_points`` (the model's), each node is mapped as the UFF
    importer maps it (:func:`jointid.data.uff.map_nodes`: ``node_map``, a name ending in the node's number,
    coordinates within ``tol_m``), and an FRF at an unmapped node is an error; without, the node number
    (or ``node_map[node]``)."""
    import pyuff  # noqa: PLC0415  (import on use)

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: UFF file does not exist — check the path")
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exception
        raise DataError(f"{path}: cannot read as a Universal File ({exc}) — export ASCII or binary UFF 58") from exc
    sets = [sets] if isinstance(sets, dict) else list(sets)
    to_m, to_n = _uff_units(sets)
    problems = Problems()
    groups = {}
    frfs = [s for s in sets if s.get("type") == 58 and s.get("func_type") == 4]
    if not frfs:
        raise DataError(f"{path}: no FRF (dataset 58, function type 4) — export the FRFs, not time data or spectra")
    names = _node_names(sets, frfs, to_m, node_map, measuring_points, tol_m)
    name = lambda node: names.get(int(node))  # noqa: E731
    for k, s in enumerate(frfs):
        where = f"{path}:dataset 58 #{k + 1} ({str(s.get('id1', '')).strip()})"
        rdir, ref_dir = int(s.get("rsp_dir", 0)), int(s.get("ref_dir", 0))
        if abs(ref_dir) not in (1, 2, 3) or int(s.get("ref_node", 0)) <= 0:
            problems.add(where, f"FRF without a reference (reference node {s.get('ref_node')}, direction {ref_dir})",
                         "export the FRF with the hammer's node and direction")
            continue
        if abs(rdir) not in (1, 2, 3):
            problems.add(where, f"response direction {rdir} is not a translation", "keep x, y, z responses only")
            continue
        f = np.asarray(s["x"], float)
        h = np.asarray(s["data"]).astype(complex) * np.sign(rdir) * np.sign(ref_dir) * to_m / to_n
        keep = f > 0
        f, h = f[keep], h[keep]
        power = _KIND.get(s.get("ordinate_spec_data_type"), 0)
        h = h / (1j * 2 * np.pi * f) ** power
        unmapped = [int(s[k]) for k in ("rsp_node", "ref_node") if name(s[k]) is None]
        if unmapped:
            problems.add(where, f"UFF node {unmapped[0]} is not a measuring point of the model (no node_map entry, "
                         f"no point name ending in {unmapped[0]}, no point within tol_m = {tol_m:g} m)",
                         "map it (node_map / --node-map), export the geometry (dataset 15) or check the units")
            continue
        key = (name(s["rsp_node"]), DIRECTIONS[abs(rdir) - 1], name(s["ref_node"]), DIRECTIONS[abs(ref_dir) - 1])
        groups[key] = (where, f, h)
    fs = _assemble(groups, state, path.name, problems) if not problems else None
    if problems:
        raise DataError(problems.condensed())
    return {state: fs}
