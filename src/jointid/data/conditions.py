"""Checks of a dataset's conditions.yaml (source, uncertainty, per-state force, currents, drive point).

Problems are collected in a :class:`jointid.data.validate.Problems` list, one line each, located by
``<file>:<line>`` (YAML syntax, repeated keys) or ``<file>:<key path>``.  See
``docs/measurement-format.md``.
"""

from __future__ import annotations

import difflib
import math

import yaml

from jointid.data.validate import DIRECTIONS, few
from jointid.yamlio import number_from_text

__all__ = ["TOP_KEYS", "STATE_KEYS", "CURRENT_KEYS", "SETUP_KEYS", "check_conditions", "hz_confirmed"]

TOP_KEYS = ("source", "states", "frequency_uncertainty_pct", "test_setup", "notes", "frequencies_in_Hz_confirmed",
            "damping_uncertainty_pct", "shape_uncertainty_pct", "computed_on_mesh")
"""``frequencies_in_Hz_confirmed: true`` says the frequencies are in Hz as written (a file format that
defines its unit, such as UFF 55, or a structure whose modes lie below 20 Hz): the kHz plausibility
check of modes.csv is skipped."""
SETUP_KEYS = ("excitation", "response_points", "response_directions", "note", "band_Hz")
STATE_KEYS = ("em_force_N", "currents", "motor_position_m", "frf_drive_point",
              "frf_drive_direction", "notes")
CURRENT_KEYS = ("exciting_current_A", "eddy_current_A")


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


def hz_confirmed(path) -> bool:
    """Whether ``conditions.yaml`` at ``path`` says ``frequencies_in_Hz_confirmed: true`` (False when
    it is missing or unreadable: its own check reports that)."""
    import yaml  # noqa: PLC0415

    try:
        with open(path, encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and data.get("frequencies_in_Hz_confirmed") is True


def check_conditions(path, label, problems, points, has_frf_states):
    """Check ``conditions.yaml`` at ``path`` (shown as ``label``); add each problem to ``problems``.

    Parameters
    ----------
    path : Path
    label : str
        File name used in the problem lines.
    problems : jointid.data.validate.Problems
    points : set of str or None
        Measuring-point names (``frf_drive_point`` must be one); None skips that check.
    has_frf_states : set of str
        States that have FRFs in frf.csv (they need a drive point).

    Returns
    -------
    dict or None
        The parsed mapping (numeric text read as numbers), or None if it is unreadable.
    """
    data = _read_yaml(path, label, problems)
    if data is None:
        return None
    _unknown_keys(problems, f"{label}:", data, TOP_KEYS)
    _as_number(data, "frequency_uncertainty_pct")
    _as_number(data, "damping_uncertainty_pct")
    _as_number(data, "shape_uncertainty_pct")
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        problems.add(f"{label}:source", "source is missing or empty",
                     "add 'source: <where the data came from: rig, date, operator, paper>'")
    for key, hint in (("frequency_uncertainty_pct", "give the 1-sigma frequency uncertainty in percent, e.g. 1.0"),
                      ("damping_uncertainty_pct", "give the 1-sigma uncertainty of each damping ratio in percent "
                                                  "of the ratio, e.g. 10"),
                      ("shape_uncertainty_pct", "give the 1-sigma noise of each modal displacement in percent of "
                                                "the RMS of that mode's displacements, e.g. 5")):
        u = data.get(key, 1.0)
        if not _is_number(u) or not 0 < u < 100:
            problems.add(f"{label}:{key}", f"{key} = {u!r} is not a number in (0, 100)", hint)
    if "computed_on_mesh" in data and not isinstance(data["computed_on_mesh"], str):
        problems.add(f"{label}:computed_on_mesh", f"computed_on_mesh = {data['computed_on_mesh']!r} is not text",
                     "remove the key (it is written by jointid's synthesiser: the digest of the mesh settings a "
                     "synthetic dataset was computed on)")
    if "frequencies_in_Hz_confirmed" in data and not isinstance(data["frequencies_in_Hz_confirmed"], bool):
        problems.add(f"{label}:frequencies_in_Hz_confirmed",
                     f"frequencies_in_Hz_confirmed = {data['frequencies_in_Hz_confirmed']!r} is not true/false",
                     "write frequencies_in_Hz_confirmed: true (or remove the key)")
    if "test_setup" in data:
        _check_setup(problems, f"{label}:test_setup", data["test_setup"], points)
    states = data.get("states")
    if not isinstance(states, dict) or not states:
        problems.add(f"{label}:states", "states is missing or not a mapping",
                     "add 'states:' with one entry per state, each with em_force_N")
        return data
    for name, cond in states.items():
        _check_state(problems, f"{label}:states.{name}", name, cond, points, has_frf_states)
    return data


def _read_yaml(path, label, problems):
    """The top-level mapping of the file, or None (problem added) if it is not UTF-8 YAML holding
    a mapping; repeated keys are reported and the mapping is still returned."""
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
    return data


def _check_state(problems, where, name, cond, points, has_frf_states) -> None:
    """Check the entry ``cond`` of state ``name`` (located ``where``); numeric text becomes numbers."""
    if not isinstance(cond, dict):
        problems.add(where, "entry is not a mapping", "write 'em_force_N: <N>' under the state")
        return
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
        _check_currents(problems, where, currents)
    if "motor_position_m" in cond and not _is_number(cond["motor_position_m"]):
        problems.add(f"{where}.motor_position_m", f"motor_position_m = "
                     f"{cond['motor_position_m']!r} is not a number",
                     "give the table position along Z in m, e.g. 0.25")
    drive = cond.get("frf_drive_point")
    if drive is not None and points is not None and str(drive) not in points:
        problems.add(f"{where}.frf_drive_point", f"frf_drive_point {drive!r} is not a measuring "
                     "point", f"use a name from the measuring-point table ({few(points)})")
    ddir = cond.get("frf_drive_direction")
    if ddir is not None and ddir not in DIRECTIONS:
        problems.add(f"{where}.frf_drive_direction", f"frf_drive_direction = {ddir!r} is not "
                     "x, y or z", "use x, y or z")
    if str(name) in has_frf_states and (drive is None or ddir is None):
        problems.add(where, "frf.csv has FRFs for this state but the drive point is not given",
                     "add frf_drive_point and frf_drive_direction")


def _check_currents(problems, where, currents) -> None:
    """Check the ``currents`` entry of a state (A, RMS magnitudes)."""
    if not isinstance(currents, dict):
        problems.add(f"{where}.currents", "currents is not a mapping",
                     f"write {', '.join(CURRENT_KEYS)} under currents")
        return
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


def _check_setup(problems, where, setup, points) -> None:
    """Check the ``test_setup`` block: where the hammer struck and where the sensor measured."""
    if not isinstance(setup, dict):
        problems.add(where, "test_setup is not a mapping",
                     "write excitation: [T05:y, ...], response_points: all, response_directions: [x, y, z]")
        return
    _unknown_keys(problems, f"{where}.", setup, SETUP_KEYS)
    exc = setup.get("excitation")
    if exc is not None:
        if not isinstance(exc, list) or not exc:
            problems.add(f"{where}.excitation", "excitation is not a non-empty list",
                         "list the hammer DOFs as '<point>:<direction>', e.g. [T05:x, T05:y, T05:z]")
        else:
            for i, lab in enumerate(exc):
                point, sep, d = str(lab).partition(":")
                if not sep or d not in DIRECTIONS:
                    problems.add(f"{where}.excitation[{i}]", f"{lab!r} is not '<point>:<direction>'",
                                 "write e.g. T05:y (direction x, y or z)")
                elif points is not None and point not in points:
                    problems.add(f"{where}.excitation[{i}]", f"{point!r} is not a measuring point",
                                 f"use a name from the measuring-point table ({few(points)})")
    pts = setup.get("response_points", "all")
    if pts != "all":
        if not isinstance(pts, list) or not pts:
            problems.add(f"{where}.response_points", "response_points is neither 'all' nor a list of points",
                         "write 'all' or a list such as [T01, T02]")
        elif points is not None:
            for name in pts:
                if str(name) not in points:
                    problems.add(f"{where}.response_points", f"{name!r} is not a measuring point",
                                 f"use names from the measuring-point table ({few(points)})")
    band = setup.get("band_Hz")
    if band is not None and not (isinstance(band, list) and len(band) == 2
                                 and all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in band)
                                 and 0 <= band[0] < band[1]):
        problems.add(f"{where}.band_Hz", f"band_Hz = {band!r} is not [low, high] in Hz with low < high",
                     "write e.g. band_Hz: [300.0, 3500.0] (the band the test analysed for modes)")
    dirs = setup.get("response_directions")
    if dirs is not None and (not isinstance(dirs, list) or not dirs or any(d not in DIRECTIONS for d in dirs)):
        problems.add(f"{where}.response_directions", f"response_directions = {dirs!r} is not a list of x, y, z",
                     "write e.g. [x, y, z] for a 3-axis accelerometer")
