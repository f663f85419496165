"""Checks of a dataset's CSV files (modes.csv, shapes.csv, frf.csv) and the problem collector.

Every check adds one line per problem to a :class:`Problems` list, formatted
``<file>:<line>: <what is wrong> — <how to fix it>``, and keeps going, so that one run reports every
problem; :func:`jointid.data.dataset.read_dataset` raises them together.  The conditions.yaml checks
are in :mod:`jointid.data.conditions`.  See ``docs/measurement-format.md``.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["DIRECTIONS", "COLUMNS", "MODE_UNCERTAINTY_COLUMNS", "Problems", "read_table", "few", "CheckedModes", "check_modes",
           "check_shapes", "check_frf"]

DIRECTIONS = ("x", "y", "z")
COLUMNS = {  # file -> (required columns, optional columns)
    "modes.csv": (("state", "mode", "freq_Hz"), ("damping_ratio", "freq_uncertainty_pct", "damping_uncertainty_pct",
                                                 "shape_uncertainty_pct")),
    "shapes.csv": (("state", "mode", "point", "direction", "value"), ()),
    "frf.csv": (("state", "point", "direction", "freq_Hz", "re", "im"), ()),
}
MODE_UNCERTAINTY_COLUMNS = ("freq_uncertainty_pct", "damping_uncertainty_pct", "shape_uncertainty_pct")
"""Optional per-mode 1-sigma uncertainties of modes.csv, in percent (an EMA measures them: jointid.ema)."""
KHZ_LIMIT_HZ = 20.0  # a dataset whose highest frequency is below this was written in kHz
RECEPTANCE_LIMIT_M_PER_N = 1e-2  # median |H| above this is not a structural receptance in m/N
_UNIT_HINTS = {  # misnamed column -> fix
    "freq_khz": "convert the values to Hz and rename the column to freq_Hz",
    "frequency_khz": "convert the values to Hz and rename the column to freq_Hz",
    "damping_pct": "divide the values by 100 and rename the column to damping_ratio",
    "damping_percent": "divide the values by 100 and rename the column to damping_ratio",
}


class Problems(list):
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


# ---------------------------------------------------------------------------------------- CSV layer
def read_table(path: Path, label: str, problems: Problems):
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


def _uncertainty(problems, where, col, raw):
    """A per-mode uncertainty in percent: a positive finite number (None and a problem otherwise).  It may
    exceed 100: an EMA can measure a damping ratio that poorly."""
    value = _float(problems, where, col, raw)
    if value is not None and not value > 0:
        problems.add(where, f"{col} = {raw} is not positive",
                     "give the 1-sigma uncertainty of this mode in percent, a positive number such as 0.05")
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
                 f"{guess}use a name from the measuring-point table ({few(points)})")
    return None


def few(names, n=4) -> str:
    """The sorted ``names`` joined, the first ``n`` only when there are more."""
    names = sorted(names)
    return ", ".join(names) if len(names) <= n else f"{', '.join(names[:n])}, ... {len(names)} in all"


# ---------------------------------------------------------------------------------------- modes
@dataclass
class CheckedModes:
    """Result of checking modes.csv: valid rows, states named anywhere, states with bad rows."""

    df: pd.DataFrame | None
    states: list[str]
    tainted: set[str]

def check_modes(path, label, problems, hz_confirmed: bool = False):
    """Check modes.csv (rows, numbering 1..n per state by increasing frequency, units); the valid
    rows as a :class:`CheckedModes`.  ``hz_confirmed`` (conditions.yaml's
    ``frequencies_in_Hz_confirmed``) skips the kHz plausibility check."""
    table = read_table(path, label, problems)
    if table is None:
        return CheckedModes(None, [], set())
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
        sigmas = tuple(_uncertainty(problems, where, col, row[col]) if col in header else np.nan
                       for col in MODE_UNCERTAINTY_COLUMNS)
        if None in (state, mode, freq, zeta) + sigmas:
            tainted.add(row["state"])
            continue
        records.append((line, state, mode, freq, zeta) + sigmas)
    if not n_rows:
        problems.add(f"{label}:2", "no modes", "add one row per measured mode below the header")
        return CheckedModes(None, [], set())
    if records:
        fmax = max(records, key=lambda r: r[3])
        if fmax[3] < KHZ_LIMIT_HZ and not hz_confirmed:
            problems.add(f"{label}:{fmax[0]}", f"largest freq_Hz = {fmax[3]:g} is below "
                         f"{KHZ_LIMIT_HZ:g} Hz; values look like kHz",
                         "multiply all frequencies by 1000 to convert to Hz (or, if they are in Hz, add "
                         "frequencies_in_Hz_confirmed: true to conditions.yaml)")
    by_state: dict[str, dict[int, tuple]] = {}
    for rec in records:
        line, state, mode, freq = rec[:4]
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
    cols = ["state", "mode", "freq_Hz", "damping_ratio", *MODE_UNCERTAINTY_COLUMNS]
    keep = ["state", "mode", "freq_Hz"] + [c for c in cols[3:] if c in header]
    df = pd.DataFrame([r[1:] for r in records], columns=cols)[keep].drop_duplicates(["state", "mode"])
    return CheckedModes(df, [s for s in dict.fromkeys(named) if s], tainted)


# ---------------------------------------------------------------------------------------- shapes, FRF
def _known_state(problems, where, state, modes_states):
    if state is None or modes_states is None or state in modes_states:
        return state is not None
    problems.add(where, f"state {state!r} is not in modes.csv",
                 f"fix the name (states: {', '.join(modes_states)}) or add its modes")
    return False


def check_shapes(path, label, problems, modes, points):
    """Check shapes.csv against the checked ``modes`` and the measuring ``points`` (None: any name);
    the valid rows as a DataFrame (``state, mode, point, direction, value``), None if unreadable."""
    table = read_table(path, label, problems)
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


def check_frf(path, label, problems, modes, points):
    """Check frf.csv (receptance in m/N) against the checked ``modes`` and the measuring ``points``;
    the valid rows as a DataFrame (``state, point, direction, freq_Hz, re, im``), None if unreadable."""
    table = read_table(path, label, problems)
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
