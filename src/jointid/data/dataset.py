"""Measured modal data: reading, validating and writing a dataset folder.

A dataset is a folder holding

* ``modes.csv``       ``state,mode,freq_Hz[,damping_ratio]`` -- one row per measured mode,
  modes numbered ``1..n`` per state in order of increasing frequency;
* ``shapes.csv``      ``state,mode,point,direction,value`` (optional) -- real mode-shape values;
* ``frf.csv``         ``state,point,direction,freq_Hz,re,im`` (optional) -- receptance in m/N,
  drive point given per state in ``conditions.yaml``;
* ``conditions.yaml`` ``source``, optional ``frequency_uncertainty_pct`` and ``states:`` with, per
  state, ``em_force_N`` and optional ``currents``, ``motor_position_m``, ``frf_drive_point``,
  ``frf_drive_direction``.

See ``docs/measurement-format.md``.  Validation collects every problem, one line each, formatted
``<file>:<line or key path>: <what is wrong> — <how to fix it>``; :func:`read_dataset` raises them
together as one :class:`~jointid.errors.DataError`.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from jointid.yamlio import number_from_text
from jointid.errors import DataError

DIRECTIONS = ("x", "y", "z")
DATASET_FILES = ("modes.csv", "shapes.csv", "frf.csv", "conditions.yaml", "README.md")
COLUMNS = {  # file -> (required columns, optional columns)
    "modes.csv": (("state", "mode", "freq_Hz"), ("damping_ratio",)),
    "shapes.csv": (("state", "mode", "point", "direction", "value"), ()),
    "frf.csv": (("state", "point", "direction", "freq_Hz", "re", "im"), ()),
}
TOP_KEYS = ("source", "states", "frequency_uncertainty_pct", "notes")
STATE_KEYS = ("em_force_N", "currents", "motor_position_m", "frf_drive_point",
              "frf_drive_direction", "notes")
CURRENT_KEYS = ("exciting_current_A", "eddy_current_A")
KHZ_LIMIT_HZ = 20.0  # a dataset whose highest frequency is below this was written in kHz
RECEPTANCE_LIMIT_M_PER_N = 1e-2  # median |H| above this is not a structural receptance in m/N
_UNIT_HINTS = {  # misnamed column -> fix
    "freq_khz": "convert the values to Hz and rename the column to freq_Hz",
    "frequency_khz": "convert the values to Hz and rename the column to freq_Hz",
    "damping_pct": "divide the values by 100 and rename the column to damping_ratio",
    "damping_percent": "divide the values by 100 and rename the column to damping_ratio",
}


class _Problems(list):
    """Problem lines ``where: what — fix``."""

    def add(self, where: str, what: str, fix: str) -> None:
        self.append(f"{where}: {what} — {fix}")

    def condensed(self, at_most: int = 3) -> list[str]:
        """The lines, with one problem repeated on more than ``at_most`` lines of a file said once,
        naming the lines (``file, 100 lines (2-101): what — fix``), in order of first appearance."""
        groups: dict[tuple, list[int]] = {}
        for text in self:
            where, _, rest = text.partition(": ")
            file, sep, line = where.rpartition(":")
            if sep and line.isdigit():
                groups.setdefault((file, rest), []).append(int(line))
            else:
                groups.setdefault((text, None), [])
        out = []
        for (file, rest), lines in groups.items():
            if rest is None:
                out.append(file)
            elif len(lines) <= at_most:
                out.extend(f"{file}:{n}: {rest}" for n in lines)
            else:
                out.append(f"{file}, {len(lines)} lines ({_line_ranges(lines)}): {rest}")
        return out


def _line_ranges(lines: list[int], shown: int = 4) -> str:
    """``2-50, 52, 60-101`` for the sorted line numbers (at most ``shown`` ranges, then ``...``)."""
    lines = sorted(set(lines))
    ranges, start = [], lines[0]
    for a, b in zip(lines, lines[1:] + [None]):
        if b != a + 1:
            ranges.append(f"{start}" if start == a else f"{start}-{a}")
            start = b
    return ", ".join(ranges[:shown]) + (", ..." if len(ranges) > shown else "")


@dataclass(frozen=True)
class Dataset:
    """A validated measured dataset.

    Attributes
    ----------
    name : str
        Folder name.
    modes : DataFrame
        Columns ``state, mode, freq_Hz`` (+ ``damping_ratio``), sorted by state then mode.
    shapes : DataFrame or None
        Columns ``state, mode, point, direction, value``.
    frf : DataFrame or None
        Columns ``state, point, direction, freq_Hz, re, im``; receptance in m/N.
    conditions : dict
        The parsed ``conditions.yaml`` (keys ``source``, ``states``, ...).
    states : list of str
        States in order of first appearance in ``modes.csv``.
    """

    name: str
    modes: pd.DataFrame
    shapes: pd.DataFrame | None
    frf: pd.DataFrame | None
    conditions: dict
    states: list[str]

    def _check_state(self, state: str) -> None:
        if state not in self.states:
            raise DataError(f"dataset {self.name}: unknown state {state!r} — use one of "
                            f"{', '.join(self.states)}")

    def _modes_of(self, state: str) -> pd.DataFrame:
        self._check_state(state)
        return self.modes[self.modes["state"] == state].sort_values("mode")

    def freqs(self, state: str) -> np.ndarray:
        """Measured natural frequencies of ``state`` in Hz, shape ``(n_modes,)``, mode order."""
        return self._modes_of(state)["freq_Hz"].to_numpy(dtype=float)

    def damping(self, state: str) -> np.ndarray | None:
        """Damping ratios of ``state``, shape ``(n_modes,)``, or None if not measured."""
        if "damping_ratio" not in self.modes.columns:
            return None
        return self._modes_of(state)["damping_ratio"].to_numpy(dtype=float)

    def state_conditions(self, state: str) -> dict:
        """The ``conditions.yaml`` entry of ``state`` (``em_force_N`` etc.)."""
        self._check_state(state)
        return dict(self.conditions["states"][state])

    def shape_matrix(self, state: str, point_dof_labels) -> np.ndarray:
        """Measured mode shapes of ``state`` at the given point DOFs.

        Parameters
        ----------
        state : str
        point_dof_labels : sequence of str or (point, direction) tuples
            Labels ``"<point>:<direction>"``, e.g. ``"T05:y"``.

        Returns
        -------
        ndarray, shape ``(n_labels, n_modes)``
            Shape values; NaN where a label was not measured (or no shapes.csv).
        """
        labels = [_split_label(lab) for lab in point_dof_labels]
        modes = self._modes_of(state)["mode"].to_numpy(dtype=int)
        out = np.full((len(labels), len(modes)), np.nan)
        if self.shapes is None:
            return out
        sh = self.shapes[self.shapes["state"] == state]
        lookup = {(p, d, int(m)): v for p, d, m, v in
                  zip(sh["point"], sh["direction"], sh["mode"], sh["value"])}
        col = {int(m): j for j, m in enumerate(modes)}
        for i, (p, d) in enumerate(labels):
            for m, j in col.items():
                out[i, j] = lookup.get((p, d, m), np.nan)
        return out

    def frf_curve(self, state: str, point: str, direction: str) -> tuple[np.ndarray, np.ndarray]:
        """Receptance at ``point``/``direction``: ``(freq_Hz (n,), H (n,) complex, m/N)``."""
        self._check_state(state)
        if self.frf is None:
            return np.empty(0), np.empty(0, complex)
        f = self.frf
        sel = f[(f["state"] == state) & (f["point"] == point) & (f["direction"] == direction)]
        sel = sel.sort_values("freq_Hz")
        return (sel["freq_Hz"].to_numpy(float),
                sel["re"].to_numpy(float) + 1j * sel["im"].to_numpy(float))


def _split_label(label) -> tuple[str, str]:
    if isinstance(label, tuple) and len(label) == 2:
        point, direction = label
    elif isinstance(label, str) and label.count(":") == 1:
        point, direction = label.split(":")
    else:
        raise DataError(f"point DOF label {label!r} is not '<point>:<direction>' — write e.g. 'T05:y'")
    if direction not in DIRECTIONS:
        raise DataError(f"point DOF label {label!r}: direction {direction!r} is not x, y or z — "
                        "write e.g. 'T05:y'")
    return str(point), direction


# ---------------------------------------------------------------------------------------- CSV layer
def _read_table(path: Path, label: str, problems: _Problems):
    """Read a CSV as strings; returns ``(header, [(line, row_dict), ...])`` or None if unusable."""
    required, optional = COLUMNS[path.name]
    allowed = required + optional
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        problems.add(f"{label}:1", "file is not UTF-8 text",
                     "save it as CSV (UTF-8, comma-separated)")
        return None
    reader = csv.reader(io.StringIO(text, newline=""))
    header = None
    rows = []
    try:
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            if header is None:
                header = [c.strip() for c in row]
                header_line = reader.line_num
                continue
            rows.append((reader.line_num, [c.strip() for c in row]))
    except csv.Error as exc:
        problems.add(f"{label}:{reader.line_num}", f"CSV syntax error ({exc})",
                     "check the quoting on that line")
        return None
    if header is None:
        problems.add(f"{label}:1", "file is empty",
                     f"write the header line {','.join(required)} and one row per entry")
        return None
    if len(header) == 1 and (";" in header[0] or "\t" in header[0]):
        sep = ";" if ";" in header[0] else "TAB"
        problems.add(f"{label}:{header_line}", f"header is not comma-separated (found '{sep}')",
                     "save as comma-separated CSV with '.' as decimal point")
        return None
    where = f"{label}:{header_line}"
    seen = set()
    for col in header:
        if col in seen:
            problems.add(where, f"column {col!r} appears twice", "keep one of them")
        seen.add(col)
        if col not in allowed:
            hint = _UNIT_HINTS.get(col.lower())
            if hint is None:
                close = difflib.get_close_matches(col, allowed, n=1, cutoff=0.6)
                guess = f" (did you mean {close[0]!r}?)" if close else ""
                hint = f"allowed columns are {', '.join(allowed)}{guess}"
            problems.add(where, f"unknown column {col!r}", hint)
    missing = [c for c in required if c not in header]
    for col in missing:
        problems.add(where, f"missing column {col!r}",
                     f"add it (required columns: {', '.join(required)})")
    if missing:
        return None
    out, rejected = [], []
    for line, row in rows:
        if len(row) != len(header):
            problems.add(f"{label}:{line}", f"row has {len(row)} fields but the header has "
                         f"{len(header)}", "check for a decimal comma (use '.') or a missing or "
                         "extra comma")
            rejected.append(dict(zip(header, row)))
            continue
        out.append((line, dict(zip(header, row))))
    return header, out, len(rows), rejected


def _float(problems, where, col, raw):
    if raw == "":
        problems.add(where, f"{col} is empty", "fill in the value or delete the row")
        return None
    try:
        value = float(raw)
    except ValueError:
        fix = ("use '.' as decimal point and no thousands separator" if "," in raw
               else "write a plain number such as 344.3")
        problems.add(where, f"{col} = {raw!r} is not a number", fix)
        return None
    if not math.isfinite(value):
        problems.add(where, f"{col} = {raw} is not a finite number",
                     "replace it by a measured value or delete the row")
        return None
    return value


def _mode_number(problems, where, raw):
    value = _float(problems, where, "mode", raw)
    if value is None:
        return None
    if value != int(value):
        problems.add(where, f"mode = {raw} is not a whole number",
                     "number the modes 1, 2, 3, ... per state")
        return None
    if value < 1:
        problems.add(where, f"mode = {raw} is below 1", "number the modes 1, 2, 3, ... per state")
        return None
    return int(value)


def _text(problems, where, col, raw):
    if raw == "":
        problems.add(where, f"{col} is empty", f"fill in the {col} name or delete the row")
        return None
    return raw


def _direction(problems, where, raw):
    d = raw.strip().lower()
    if d in DIRECTIONS:
        return d
    if d in ("rx", "ry", "rz"):
        problems.add(where, f"direction = {raw!r} is a rotation",
                     "keep translations x, y, z only; rotations are not supported")
    else:
        problems.add(where, f"direction = {raw!r} is not x, y or z",
                     "use x (lateral), y (vertical) or z (feed)")
    return None


def _point(problems, where, raw, points):
    name = _text(problems, where, "point", raw)
    if name is None or points is None or name in points:
        return name
    close = difflib.get_close_matches(name, sorted(points), n=1, cutoff=0.6)
    guess = f"did you mean {close[0]!r}? " if close else ""
    problems.add(where, f"point {name!r} is not a measuring point",
                 f"{guess}use a name from the measuring-point table ({_few(points)})")
    return None


def _few(names, n=4) -> str:
    names = sorted(names)
    return ", ".join(names) if len(names) <= n else f"{', '.join(names[:n])}, ... {len(names)} in all"


# ---------------------------------------------------------------------------------------- modes
@dataclass
class _Modes:
    """Result of checking modes.csv: valid rows, states named anywhere, states with bad rows."""

    df: pd.DataFrame | None
    states: list[str]
    tainted: set[str]

def _check_modes(path, label, problems):
    table = _read_table(path, label, problems)
    if table is None:
        return _Modes(None, [], set())
    header, rows, n_rows, rejected = table
    has_damping = "damping_ratio" in header
    records = []
    tainted = {r.get("state", "") for r in rejected}  # states with rejected rows: skip set checks
    named = [r.get("state", "") for r in rejected]
    for line, row in rows:
        where = f"{label}:{line}"
        state = _text(problems, where, "state", row["state"])
        mode = _mode_number(problems, where, row["mode"])
        freq = _float(problems, where, "freq_Hz", row["freq_Hz"])
        if freq is not None and freq <= 0:
            problems.add(where, f"freq_Hz = {row['freq_Hz']} is not positive",
                         "natural frequencies are > 0 Hz; check the sign and the column")
            freq = None
        zeta = np.nan
        if has_damping:
            raw = row["damping_ratio"]
            zeta = _float(problems, where, "damping_ratio", raw)
            if zeta is not None and zeta > 1:
                problems.add(where, f"damping_ratio = {raw} looks like percent",
                             "divide by 100 (damping is a ratio of critical, 0 < ratio < 1)")
                zeta = None
            elif zeta is not None and not 0 < zeta < 1:
                problems.add(where, f"damping_ratio = {raw} is outside (0, 1)",
                             "give the viscous damping ratio of critical, e.g. 0.02 for 2 %")
                zeta = None
        named.append(row["state"])
        if None in (state, mode, freq, zeta):
            tainted.add(row["state"])
            continue
        records.append((line, state, mode, freq, zeta))
    if not n_rows:
        problems.add(f"{label}:2", "no modes", "add one row per measured mode below the header")
        return _Modes(None, [], set())
    if records:
        fmax = max(records, key=lambda r: r[3])
        if fmax[3] < KHZ_LIMIT_HZ:
            problems.add(f"{label}:{fmax[0]}", f"largest freq_Hz = {fmax[3]:g} is below "
                         f"{KHZ_LIMIT_HZ:g} Hz; values look like kHz",
                         "multiply all frequencies by 1000 to convert to Hz")
    by_state: dict[str, dict[int, tuple]] = {}
    for rec in records:
        line, state, mode, freq, _ = rec
        modes = by_state.setdefault(state, {})
        if mode in modes:
            problems.add(f"{label}:{line}", f"duplicate mode {mode} of state {state} (also on line "
                         f"{modes[mode][0]})", "keep one row per (state, mode)")
            tainted.add(state)
            continue
        modes[mode] = rec
    for state, modes in by_state.items():
        if state in tainted:
            continue
        numbers = sorted(modes)
        if numbers != list(range(1, len(numbers) + 1)):
            bad = next(m for i, m in enumerate(numbers) if m != i + 1)
            problems.add(f"{label}:{modes[bad][0]}", f"state {state} has modes "
                         f"{', '.join(map(str, numbers))}; mode {bad} breaks the sequence",
                         f"number the modes 1..{len(numbers)} without gaps")
            continue
        for m in numbers[1:]:
            if modes[m][3] < modes[m - 1][3]:
                problems.add(f"{label}:{modes[m][0]}", f"mode {m} of state {state} "
                             f"({modes[m][3]:g} Hz) is below mode {m - 1} ({modes[m - 1][3]:g} Hz)",
                             "number the modes by increasing frequency")
    cols = ["state", "mode", "freq_Hz"] + (["damping_ratio"] if has_damping else [])
    good = [r[1:] if has_damping else r[1:4] for r in records]
    df = pd.DataFrame(good, columns=cols).drop_duplicates(["state", "mode"])
    return _Modes(df, [s for s in dict.fromkeys(named) if s], tainted)


# ---------------------------------------------------------------------------------------- shapes, FRF
def _known_state(problems, where, state, modes_states):
    if state is None or modes_states is None or state in modes_states:
        return state is not None
    problems.add(where, f"state {state!r} is not in modes.csv",
                 f"fix the name (states: {', '.join(modes_states)}) or add its modes")
    return False


def _check_shapes(path, label, problems, modes, points):
    table = _read_table(path, label, problems)
    if table is None:
        return None
    _, rows, _, _ = table
    states = modes.states if modes.df is not None else None
    known_modes = None if modes.df is None else set(zip(modes.df["state"], modes.df["mode"]))
    records, seen, first_line = [], {}, {}
    for line, row in rows:
        where = f"{label}:{line}"
        state = _text(problems, where, "state", row["state"])
        ok = _known_state(problems, where, state, states)
        mode = _mode_number(problems, where, row["mode"])
        if (ok and mode is not None and known_modes is not None and state not in modes.tainted
                and (state, mode) not in known_modes):
            problems.add(where, f"mode {mode} of state {state} is not in modes.csv",
                         "delete these shape rows or add the mode to modes.csv")
            ok = False
        point = _point(problems, where, row["point"], points)
        direction = _direction(problems, where, row["direction"])
        value = _float(problems, where, "value", row["value"])
        if not ok or None in (mode, point, direction, value):
            continue
        key = (state, mode, point, direction)
        if key in seen:
            problems.add(where, f"duplicate shape value for state {state}, mode {mode}, "
                         f"{point}:{direction} (also on line {seen[key]})", "keep one row")
            continue
        seen[key] = line
        first_line.setdefault((state, mode), line)
        records.append(key + (value,))
    df = pd.DataFrame(records, columns=["state", "mode", "point", "direction", "value"])
    for (state, mode), grp in df.groupby(["state", "mode"], sort=False):
        if not np.any(grp["value"].to_numpy() != 0):
            problems.add(f"{label}:{first_line[(state, mode)]}",
                         f"mode shape {mode} of state {state} is all zeros",
                         "check the export (a mode shape needs a non-zero value) or delete its rows")
    return df


def _check_frf(path, label, problems, modes, points):
    table = _read_table(path, label, problems)
    if table is None:
        return None
    _, rows, _, _ = table
    states = modes.states if modes.df is not None else None
    records, seen = [], {}
    for line, row in rows:
        where = f"{label}:{line}"
        state = _text(problems, where, "state", row["state"])
        ok = _known_state(problems, where, state, states)
        point = _point(problems, where, row["point"], points)
        direction = _direction(problems, where, row["direction"])
        freq = _float(problems, where, "freq_Hz", row["freq_Hz"])
        if freq is not None and freq <= 0:
            problems.add(where, f"freq_Hz = {row['freq_Hz']} is not positive",
                         "delete the 0 Hz line (receptance is undefined there) or fix the sign")
            freq = None
        re_ = _float(problems, where, "re", row["re"])
        im_ = _float(problems, where, "im", row["im"])
        if not ok or None in (point, direction, freq, re_, im_):
            continue
        key = (state, point, direction, freq)
        if key in seen:
            problems.add(where, f"duplicate FRF line for state {state}, {point}:{direction} at "
                         f"{freq:g} Hz (also on line {seen[key]})", "keep one line per frequency")
            continue
        seen[key] = line
        records.append(key + (re_, im_))
    df = pd.DataFrame(records, columns=["state", "point", "direction", "freq_Hz", "re", "im"])
    if len(df):
        mag = np.median(np.hypot(df["re"], df["im"]))
        if mag > RECEPTANCE_LIMIT_M_PER_N:
            problems.add(f"{label}:2", f"median |H| = {mag:.3g} is too large for a receptance "
                         "in m/N; values look like accelerance ((m/s^2)/N) or mm/N",
                         "convert to receptance in m/N (accelerance / -(2*pi*f)^2; mm/N / 1000)")
    return df


# ---------------------------------------------------------------------------------------- conditions
def _yaml_duplicates(node, path=""):
    """Yield ``(key_path, line)`` for keys repeated in a YAML mapping (safe_load keeps the last)."""
    if isinstance(node, yaml.MappingNode):
        seen = set()
        for key, value in node.value:
            name = str(key.value)
            sub = f"{path}.{name}" if path else name
            if name in seen:
                yield sub, key.start_mark.line + 1
            seen.add(name)
            yield from _yaml_duplicates(value, sub)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            yield from _yaml_duplicates(item, f"{path}[{i}]")


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _as_number(mapping, key) -> None:
    """Numeric text at ``mapping[key]`` as float, in place: PyYAML (YAML 1.1) reads ``1e3`` or
    ``2.0e8`` as strings.  The rule is config.yaml's (:func:`jointid.yamlio.number_from_text`);
    text that is no finite number stays text and is reported by the caller."""
    if isinstance(mapping, dict) and key in mapping:
        value = number_from_text(mapping[key])
        if value is not None and math.isfinite(value):
            mapping[key] = value


def _unknown_keys(problems, prefix, mapping, allowed):
    """Report keys of ``mapping`` not in ``allowed``; the location is ``prefix + key``."""
    for key in mapping:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
            guess = f" (did you mean {close[0]!r}?)" if close else ""
            problems.add(f"{prefix}{key}", f"unknown key {key!r}",
                         f"allowed keys are {', '.join(allowed)}{guess}")


def _check_conditions(path, label, problems, points, has_frf_states):
    try:
        text = path.read_text(encoding="utf-8-sig")
        node = yaml.compose(text)
        data = yaml.safe_load(text)
    except UnicodeDecodeError:
        problems.add(f"{label}:1", "file is not UTF-8 text", "save it as UTF-8")
        return None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else 1
        what = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        problems.add(f"{label}:{line}", f"YAML syntax error: {what}",
                     "fix the indentation, colon or quoting on that line")
        return None
    for key, line in _yaml_duplicates(node):
        problems.add(f"{label}:{line}", f"key {key} appears twice", "keep one of them")
    if data is None:
        problems.add(f"{label}:1", "file is empty",
                     "write 'source: ...' and 'states:' with em_force_N per state")
        return None
    if not isinstance(data, dict):
        problems.add(f"{label}:1", f"top level is a {type(data).__name__}, not a mapping",
                     "write 'source: ...' and 'states:' with em_force_N per state")
        return None
    _unknown_keys(problems, f"{label}:", data, TOP_KEYS)
    _as_number(data, "frequency_uncertainty_pct")
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        problems.add(f"{label}:source", "source is missing or empty",
                     "add 'source: <where the data came from: rig, date, operator, paper>'")
    if "frequency_uncertainty_pct" in data:
        u = data["frequency_uncertainty_pct"]
        if not _is_number(u) or not 0 < u < 100:
            problems.add(f"{label}:frequency_uncertainty_pct",
                         f"frequency_uncertainty_pct = {u!r} is not a number in (0, 100)",
                         "give the 1-sigma frequency uncertainty in percent, e.g. 1.0")
    states = data.get("states")
    if not isinstance(states, dict) or not states:
        problems.add(f"{label}:states", "states is missing or not a mapping",
                     "add 'states:' with one entry per state, each with em_force_N")
        return data
    for name, cond in states.items():
        where = f"{label}:states.{name}"
        if not isinstance(cond, dict):
            problems.add(where, "entry is not a mapping", "write 'em_force_N: <N>' under the state")
            continue
        _unknown_keys(problems, f"{where}.", cond, STATE_KEYS)
        for key in ("em_force_N", "motor_position_m"):
            _as_number(cond, key)
        if isinstance(cond.get("currents"), dict):
            for key in CURRENT_KEYS:
                _as_number(cond["currents"], key)
        if "em_force_N" not in cond:
            problems.add(where, "em_force_N is missing",
                         "add em_force_N: <vertical motor attraction in N, 0 when powered off>")
        else:
            f = cond["em_force_N"]
            if not _is_number(f):
                problems.add(f"{where}.em_force_N", f"em_force_N = {f!r} is not a number",
                             "write the force in N, e.g. 1000.0")
            elif f < 0:
                problems.add(f"{where}.em_force_N", f"em_force_N = {f} is negative",
                             "give the attraction as a magnitude (>= 0 N)")
        currents = cond.get("currents")
        if currents is not None:
            if not isinstance(currents, dict):
                problems.add(f"{where}.currents", "currents is not a mapping",
                             f"write {', '.join(CURRENT_KEYS)} under currents")
            else:
                _unknown_keys(problems, f"{where}.currents.", currents, CURRENT_KEYS)
                for key in CURRENT_KEYS:
                    if key in currents:
                        c = currents[key]
                        if not _is_number(c):
                            problems.add(f"{where}.currents.{key}", f"{key} = {c!r} is not a number",
                                         "write the current in A, e.g. 4.5")
                        elif c < 0:
                            problems.add(f"{where}.currents.{key}", f"{key} = {c} is negative",
                                         "give the RMS current magnitude (>= 0 A)")
        if "motor_position_m" in cond and not _is_number(cond["motor_position_m"]):
            problems.add(f"{where}.motor_position_m", f"motor_position_m = "
                         f"{cond['motor_position_m']!r} is not a number",
                         "give the table position along Z in m, e.g. 0.25")
        drive = cond.get("frf_drive_point")
        if drive is not None and points is not None and str(drive) not in points:
            problems.add(f"{where}.frf_drive_point", f"frf_drive_point {drive!r} is not a measuring "
                         "point", f"use a name from the measuring-point table ({_few(points)})")
        ddir = cond.get("frf_drive_direction")
        if ddir is not None and ddir not in DIRECTIONS:
            problems.add(f"{where}.frf_drive_direction", f"frf_drive_direction = {ddir!r} is not "
                         "x, y or z", "use x, y or z")
        if str(name) in has_frf_states and (drive is None or ddir is None):
            problems.add(where, "frf.csv has FRFs for this state but the drive point is not given",
                         "add frf_drive_point and frf_drive_direction")
    return data


# ---------------------------------------------------------------------------------------- dataset
def modes_states(folder) -> list[str] | None:
    """State names in ``folder/modes.csv`` (each once), without checking the rows.

    A cheap look for the configuration check (does the dataset hold the states that use it?);
    :func:`read_dataset` does the full validation.  None if there is no readable modes.csv with a
    ``state`` column.
    """
    counts = modes_per_state(folder)
    return None if counts is None else list(counts)


def modes_per_state(folder) -> dict[str, int] | None:
    """Number of rows of each state in ``folder/modes.csv`` (in order of first appearance), without
    checking the rows; None if there is no readable modes.csv with a ``state`` column."""
    path = Path(folder) / "modes.csv"
    try:
        table = _read_table(path, str(path), _Problems()) if path.is_file() else None
    except OSError:
        return None
    if table is None:
        return None
    _, rows, _, rejected = table
    counts: dict[str, int] = {}
    for row in [r for _, r in rows] + rejected:
        state = (row.get("state") or "").strip()
        if state:
            counts[state] = counts.get(state, 0) + 1
    return counts


def _point_names(measuring_points, problems):
    if measuring_points is None:
        return None
    if "point" not in getattr(measuring_points, "columns", ()):
        problems.add("measuring_points:1", "missing column 'point'",
                     "pass the table with columns point, x_m, y_m, z_m")
        return None
    return set(map(str, measuring_points["point"]))


def _load(folder, measuring_points=None, expected_states=None):
    problems = _Problems()
    folder = Path(folder)
    if not folder.exists():
        problems.add(str(folder), "dataset folder does not exist",
                     "check the path (a dataset is a folder with modes.csv and conditions.yaml)")
        return problems, None
    if not folder.is_dir():
        problems.add(str(folder), "is a file, not a folder",
                     "pass the folder that holds modes.csv and conditions.yaml")
        return problems, None
    points = _point_names(measuring_points, problems)
    label = lambda name: str(folder / name)  # noqa: E731
    modes, shapes, frf = _Modes(None, [], set()), None, None
    if (folder / "modes.csv").is_file():
        modes = _check_modes(folder / "modes.csv", label("modes.csv"), problems)
    else:
        problems.add(label("modes.csv"), "file is missing",
                     "add modes.csv with columns state,mode,freq_Hz")
    if (folder / "shapes.csv").is_file():
        shapes = _check_shapes(folder / "shapes.csv", label("shapes.csv"), problems, modes, points)
    if (folder / "frf.csv").is_file():
        frf = _check_frf(folder / "frf.csv", label("frf.csv"), problems, modes, points)
    frf_states = set() if frf is None else set(frf["state"])
    conditions = None
    if (folder / "conditions.yaml").is_file():
        conditions = _check_conditions(folder / "conditions.yaml", label("conditions.yaml"),
                                       problems, points, frf_states)
    else:
        problems.add(label("conditions.yaml"), "file is missing",
                     "add conditions.yaml with 'source:' and 'states:' (em_force_N per state)")
    mode_states = modes.states
    cond_states = None
    if isinstance(conditions, dict) and isinstance(conditions.get("states"), dict):
        cond_states = [str(s) for s in conditions["states"]]
    if modes.df is not None and cond_states is not None:
        for s in mode_states:
            if s not in cond_states:
                problems.add(f"{label('conditions.yaml')}:states", f"state {s!r} of modes.csv is "
                             "missing", f"add states.{s} with em_force_N")
        for s in cond_states:
            if s not in mode_states:
                problems.add(f"{label('conditions.yaml')}:states.{s}", "state is not in modes.csv",
                             f"fix the name (states: {', '.join(mode_states)}) or remove it")
    for s in expected_states or ():
        if modes.df is not None and s not in mode_states:
            problems.add(label("modes.csv"), f"expected state {s!r} has no modes",
                         f"add its modes or measure state {s}")
        if cond_states is not None and s not in cond_states:
            problems.add(f"{label('conditions.yaml')}:states", f"expected state {s!r} is missing",
                         f"add states.{s} with em_force_N")
    if problems:
        return problems, None
    if isinstance(conditions.get("states"), dict):
        conditions["states"] = {str(k): v for k, v in conditions["states"].items()}
    order = {s: i for i, s in enumerate(mode_states)}
    df = modes.df
    modes = (df.assign(_o=df["state"].map(order)).sort_values(["_o", "mode"])
             .drop(columns="_o").reset_index(drop=True))
    return problems, Dataset(name=folder.resolve().name, modes=modes,
                             shapes=shapes if shapes is not None and len(shapes) else None,
                             frf=frf if frf is not None and len(frf) else None,
                             conditions=conditions, states=mode_states)


def validate_dataset(folder, measuring_points=None, expected_states=None) -> list[str]:
    """Check a dataset folder; return every problem as one line (empty list if valid).

    Parameters
    ----------
    folder : path
        Dataset folder.
    measuring_points : DataFrame, optional
        Columns ``point, x_m, y_m, z_m``; when given, point names in shapes.csv, frf.csv and
        ``frf_drive_point`` must appear in it.
    expected_states : sequence of str, optional
        States that must be present in modes.csv and conditions.yaml.
    """
    return _load(folder, measuring_points, expected_states)[0].condensed()


def read_dataset(folder, measuring_points=None, expected_states=None) -> Dataset:
    """Read and validate a dataset folder; raise one :class:`DataError` listing every problem."""
    problems, dataset = _load(folder, measuring_points, expected_states)
    if problems:
        raise DataError(problems.condensed())
    return dataset


def write_dataset(folder, modes: pd.DataFrame, shapes: pd.DataFrame | None = None,
                  frf: pd.DataFrame | None = None, *, conditions: dict,
                  measuring_points=None) -> Dataset:
    """Write a dataset folder atomically and return it as read back.

    The files are written into a temporary sibling folder which is validated and then renamed to
    ``folder`` (an existing dataset folder is replaced: renamed aside, swapped, then deleted), so a
    reader never sees a half-written dataset.  Nothing is written if validation fails; a folder
    holding files other than dataset files is never replaced.

    Parameters
    ----------
    folder : path
    modes : DataFrame
        ``state, mode, freq_Hz`` (+ ``damping_ratio``).
    shapes, frf : DataFrame, optional
        ``state, mode, point, direction, value`` / ``state, point, direction, freq_Hz, re, im``.
    conditions : dict
        Content of conditions.yaml: ``{"source": ..., "states": {state: {"em_force_N": ...}}}``.
    measuring_points : DataFrame, optional
        Used to validate point names before the swap.

    Raises
    ------
    DataError
        If the data are invalid or ``folder`` holds foreign files.
    """
    folder = Path(folder)
    if folder.exists():
        foreign = sorted(p.name for p in folder.iterdir() if p.name not in DATASET_FILES)
        if not folder.is_dir() or foreign:
            raise DataError(f"{folder}: exists and holds files that are not dataset files "
                            f"({', '.join(foreign) or 'it is a file'}) — write to a new folder or "
                            "move them away")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=folder.parent))
    try:
        _frame_to_csv(modes, COLUMNS["modes.csv"], tmp / "modes.csv")
        if shapes is not None:
            _frame_to_csv(shapes, COLUMNS["shapes.csv"], tmp / "shapes.csv")
        if frf is not None:
            _frame_to_csv(frf, COLUMNS["frf.csv"], tmp / "frf.csv")
        with open(tmp / "conditions.yaml", "w", encoding="utf-8") as fh:
            yaml.safe_dump(_plain(conditions), fh, sort_keys=False, allow_unicode=True)
        problems = validate_dataset(tmp, measuring_points)
        if problems:
            raise DataError([p.replace(str(tmp), str(folder)) for p in problems])
        _swap_in(tmp, folder)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return read_dataset(folder, measuring_points)


def _frame_to_csv(df, columns, path):
    required, optional = columns
    cols = list(required) + [c for c in optional if c in df.columns]
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise DataError(f"{path.name}: table to write lacks column(s) {', '.join(missing)} — "
                        f"provide {', '.join(required)}")
    df.loc[:, cols].to_csv(path, index=False, lineterminator="\n")


def _plain(obj):
    """Convert numpy scalars and containers into plain Python for yaml.safe_dump."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _swap_in(tmp: Path, folder: Path) -> None:
    if not folder.exists():
        os.replace(tmp, folder)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.old-", dir=folder.parent))
    old.rmdir()
    os.replace(folder, old)
    try:
        os.replace(tmp, folder)
    except OSError:
        os.replace(old, folder)
        raise
    shutil.rmtree(old)
