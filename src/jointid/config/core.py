"""Configuration layer: load config.yaml, fill defaults, validate, hash, document.

The JSON-Schema ``workflow/schemas/config.schema.yaml`` is the single source of the keys, types,
ranges, defaults and descriptions.  This module adds what a schema cannot express (semantic
checks across keys: geometry fits, bound order, DOE size, mesh size ...) and turns every problem
into one user-facing line::

    config.yaml: rig.base.length_m: -1.1 must be > 0 — give the base length in metres

All problems are collected and raised together as one :class:`jointid.errors.ConfigError`.

Public API
----------
load_config(path_or_dict, overrides=None) -> dict
check_config(cfg, source="config.yaml") -> (dict, list[str])
config_hash(cfg, keys=None) -> str
section(cfg, *keys) -> Any
load_schema(path=None) -> dict, find_schema() -> Path
config_reference_markdown(schema) -> str
estimate_node_count(cfg) -> int

Command line::

    python -m jointid.config.core check [config.yaml] [--set key=value ...]
    python -m jointid.config.core reference [--output docs/config-reference.md]
    python -m jointid.config.core hash [config.yaml] [key ...]
"""

from __future__ import annotations

import argparse
import copy
import difflib
import functools
import hashlib
import json
import math
import os
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from jointid.errors import ConfigError
from jointid.yamlio import Loader, deep_merge, number_from_text, read_yaml

__all__ = [
    "MAX_NODES",
    "SCHEMA_ENV",
    "SCHEMA_RELPATH",
    "check_config",
    "config_hash",
    "config_reference_markdown",
    "estimate_node_count",
    "find_schema",
    "load_config",
    "load_schema",
    "main",
    "number_from_text",
    "section",
]

SCHEMA_RELPATH = Path("workflow") / "schemas" / "config.schema.yaml"
SCHEMA_ENV = "JOINTID_SCHEMA"
SCHEMA_TITLE = "jointid configuration"
MAX_NODES = 2_000_000
"""Largest estimated FE node count accepted by the semantic mesh check."""

_POINT_RE = re.compile(r"^[TB](0[1-9]|1[0-8])$")
_DEFAULT_SOURCE = "config.yaml"

# unit words for "how to fix" phrases, from the key's unit suffix (longest suffix first)
_UNIT_WORDS = (
    ("_kg_per_m3", "kg/m^3"),
    ("_N_per_m3", "N/m^3"),
    ("_N_per_m", "N/m"),
    ("_per_s", "1/s"),
    ("_pct", "percent"),
    ("_Hz", "hertz"),
    ("_Pa", "pascals"),
    ("_kg", "kilograms"),
    ("_N", "newtons"),
    ("_m", "metres"),
    ("_s", "seconds"),
)


# ------------------------------------------------------------------------------------- schema
def find_schema() -> Path:
    """Locate ``workflow/schemas/config.schema.yaml``.

    Order: the file named by the environment variable ``JOINTID_SCHEMA``; else the first jointid
    schema found walking up from the current working directory; else walking up from this file
    (works for a source checkout and an editable install).

    Returns
    -------
    Path
        Absolute path of the schema file.

    Raises
    ------
    ConfigError
        If ``JOINTID_SCHEMA`` names a missing file or no schema is found.
    """
    env = os.environ.get(SCHEMA_ENV)
    if env:
        path = Path(env).expanduser()
        if not path.is_file():
            raise ConfigError(
                f"{SCHEMA_ENV}={env}: schema file not found — point {SCHEMA_ENV} to "
                f"{SCHEMA_RELPATH.as_posix()} of a jointid checkout, or unset it"
            )
        return path.resolve()
    starts = [Path.cwd(), Path(__file__).resolve().parent]
    for start in starts:
        for folder in (start, *start.parents):
            candidate = folder / SCHEMA_RELPATH
            if candidate.is_file() and _is_jointid_schema(candidate):
                return candidate.resolve()
    raise ConfigError(
        f"{SCHEMA_RELPATH.as_posix()}: jointid config schema not found above the working directory "
        f"or the installed package — run from the jointid repository or set {SCHEMA_ENV}=/path/to/config.schema.yaml"
    )


def _is_jointid_schema(path: Path) -> bool:
    """True if ``path`` is jointid's schema (other Snakemake projects use the same file name)."""
    try:
        with path.open(encoding="utf-8") as fh:
            head = fh.read(4000)
    except OSError:
        return False
    return re.search(rf"^title:\s*{re.escape(SCHEMA_TITLE)}\s*$", head, re.M) is not None


@functools.lru_cache(maxsize=8)
def _load_schema_cached(path: str, mtime: float) -> dict:
    data = read_yaml(Path(path), path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: not a JSON-Schema mapping — restore {SCHEMA_RELPATH.as_posix()} from git")
    return data


def load_schema(path: str | os.PathLike | None = None) -> dict:
    """Return the config JSON-Schema as a dict (a fresh deep copy).

    Parameters
    ----------
    path : path-like, optional
        Schema file; default :func:`find_schema`.
    """
    path = Path(path) if path is not None else find_schema()
    if not path.is_file():
        raise ConfigError(f"{path}: schema file not found — check the path")
    return copy.deepcopy(_load_schema_cached(str(path.resolve()), path.stat().st_mtime))


# ----------------------------------------------------------------------------------- formatting
def _fmt_num(x: Any) -> str:
    """Short exact text of a number: 2e12, 0.0004, -1.1, 3500."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if isinstance(x, int):
        return str(x)
    if not math.isfinite(x):
        return str(x)
    if x == int(x) and abs(x) < 1e6:
        return str(int(x))
    for digits in range(1, 18):
        text = f"{x:.{digits}g}"
        if float(text) == x:
            break
    return re.sub(r"e([+-]?)0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), text)


def _show(value: Any, limit: int = 60) -> str:
    """Value as shown in a problem line."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif value is None:
        text = "null"
    elif isinstance(value, (int, float)):
        text = _fmt_num(value)
    elif isinstance(value, str):
        text = repr(value)
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(_show(v, limit) for v in value) + "]"
    elif isinstance(value, Mapping):
        text = "{" + ", ".join(f"{k}: {_show(v, limit)}" for k, v in value.items()) + "}"
    else:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _text_of(text: str, expected: list[str]) -> bool:
    """Whether ``text`` spells a value of one of the ``expected`` JSON-schema types (e.g. 'true', '8')."""
    import yaml

    try:
        val = yaml.safe_load(text)
    except yaml.YAMLError:
        return False
    kinds = {"boolean": lambda v: isinstance(v, bool),
             "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
             "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)}
    return any(kinds.get(e, lambda v: False)(val) for e in expected)


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "true/false"
    if value is None:
        return "empty"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "text"
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, Mapping):
        return "a mapping"
    return type(value).__name__


_EXPECTED = {
    "object": "a mapping",
    "array": "a list",
    "number": "a number",
    "integer": "a whole number",
    "string": "text",
    "boolean": "true or false",
    "null": "empty",
}


def _dotted(parts: Iterable[Any]) -> str:
    out = ""
    for p in parts:
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            out += ("." if out else "") + str(p)
    return out or "(top level)"


def _last_key(parts: list[Any]) -> str:
    for p in reversed(parts):
        if not isinstance(p, int):
            return str(p)
    return ""


def _unit_words(key: str) -> str:
    for suffix, words in _UNIT_WORDS:
        if key.endswith(suffix):
            return words
    return ""


def _bounds_text(schema: Mapping) -> str:
    lo = hi = ""
    if "exclusiveMinimum" in schema:
        lo = f"> {_fmt_num(schema['exclusiveMinimum'])}"
    elif "minimum" in schema:
        lo = f">= {_fmt_num(schema['minimum'])}"
    if "exclusiveMaximum" in schema:
        hi = f"< {_fmt_num(schema['exclusiveMaximum'])}"
    elif "maximum" in schema:
        hi = f"<= {_fmt_num(schema['maximum'])}"
    return " and ".join(t for t in (lo, hi) if t)


def _has_bounds(schema: Mapping) -> tuple[bool, bool]:
    lo = "minimum" in schema or "exclusiveMinimum" in schema
    hi = "maximum" in schema or "exclusiveMaximum" in schema
    return lo, hi


def _fix_phrase(schema: Mapping, key: str) -> str:
    """'give the <title> in <unit>' style advice for a leaf schema."""
    title = schema.get("title") or key.replace("_", " ")
    typ = schema.get("type")
    unit = _unit_words(key)
    if "enum" in schema:
        return "choose one of: " + ", ".join(str(v) for v in schema["enum"])
    if typ in ("number", "integer"):
        text = f"give the {title}"
        if typ == "integer":
            text += " as a whole number"
        elif unit:
            text += f" in {unit}"
        has_lo, has_hi = _has_bounds(schema)
        if has_lo and has_hi:
            text += f" ({_bounds_text(schema)})"
        elif typ == "integer" and has_lo:
            text += f" {_bounds_text(schema)}"
        return text
    if typ == "array":
        text = f"give the {title} as a list"
        if unit:
            text += f" in {unit}"
        if "default" in schema:
            text += f", e.g. {_show(schema['default'])}"
        return text
    if typ == "object":
        props = list(schema.get("properties", {}))
        if props:
            return f"write {key} as a mapping with keys {', '.join(props)}"
        return f"write {key} as a mapping (key: value lines)"
    if typ == "string":
        text = f"give the {title} as text"
        if "default" in schema:
            text += f", e.g. {schema['default']!r}"
        return text
    return f"see docs/config-reference.md for {key}"


def _need_phrase(schema: Mapping, key: str) -> str:
    """'the <title> in <unit>, one of ...' describing a missing value."""
    text = "the " + (schema.get("title") or key.replace("_", " "))
    unit = _unit_words(key)
    if unit and schema.get("type") == "number":
        text += f" in {unit}"
    if "enum" in schema:
        text += ", one of " + ", ".join(str(v) for v in schema["enum"])
    elif _bounds_text(schema):
        text += f", {_bounds_text(schema)}"
    return text


def _suggest(word: str, choices: Iterable[str]) -> str | None:
    """Closest choice (difflib), else the only choice that starts with ``word``; None if neither."""
    choices = [str(c) for c in choices]
    match = difflib.get_close_matches(str(word), choices, n=1, cutoff=0.6)
    if match:
        return match[0]
    prefixed = [c for c in choices if len(str(word)) >= 2 and c.lower().startswith(str(word).lower())]
    return prefixed[0] if len(prefixed) == 1 else None


# ------------------------------------------------------------------ defaults and normalisation
def _subschema(schema: Mapping, key: str) -> Mapping | None:
    props = schema.get("properties", {})
    if key in props:
        return props[key]
    for pattern, sub in schema.get("patternProperties", {}).items():
        if re.search(pattern, key):
            return sub
    extra = schema.get("additionalProperties")
    return extra if isinstance(extra, Mapping) else None


def _types(schema: Mapping) -> set[str]:
    typ = schema.get("type")
    if typ is None:
        return set()
    return {typ} if isinstance(typ, str) else set(typ)


def _normalise(value: Any, schema: Mapping | None, path: list, problems: list[tuple[list, str]]) -> Any:
    """Fill defaults, coerce numeric text and int/float per schema; note non-finite numbers.

    Returns a new value (plain dicts/lists); the input is not modified.
    """
    schema = schema or {}
    types = _types(schema)
    if isinstance(value, Mapping):
        out = {str(k) if not isinstance(k, str) else k: v for k, v in value.items()}
        # an empty value (null) counts as not given: a later config file removes a key an earlier one set
        out = {k: v for k, v in out.items() if not _unset(v, _subschema(schema, k))}
        if "object" in types:
            _fill_defaults(out, schema)
        return {k: _normalise(v, _subschema(schema, k), path + [k], problems) for k, v in out.items()}
    if isinstance(value, (list, tuple)):
        items = schema.get("items") if isinstance(schema.get("items"), Mapping) else None
        return [_normalise(v, items, path + [i], problems) for i, v in enumerate(value)]
    if hasattr(value, "item") and callable(value.item) and not isinstance(value, (str, bytes)):
        try:  # numpy scalar
            value = value.item()
        except (TypeError, ValueError):
            pass
    if types & {"number", "integer"} and (number := number_from_text(value)) is not None:
        value = number
    if isinstance(value, float) and not math.isfinite(value):
        problems.append((path, f"{_fmt_num(value)} is not a finite number — give a finite value"))
        return value
    if isinstance(value, bool):
        return value
    if "integer" in types and isinstance(value, float) and value.is_integer():
        return int(value)
    if "number" in types and "integer" not in types and isinstance(value, int):
        return float(value)
    return value


def _unset(value: Any, schema: Mapping | None) -> bool:
    """Whether a key holding ``value`` counts as not given: null for a known key that is not nullable.

    Unknown keys (no schema) keep their null, so a misspelt key is still reported.
    """
    return value is None and schema is not None and "null" not in _types(schema)


def _fill_defaults(out: dict, schema: Mapping) -> None:
    """Set missing ``properties`` defaults, then those of ``then`` when ``if`` holds (in place)."""
    for key, sub in schema.get("properties", {}).items():
        if key not in out and "default" in sub:
            out[key] = copy.deepcopy(sub["default"])
    if isinstance(schema.get("if"), Mapping) and isinstance(schema.get("then"), Mapping):
        import jsonschema

        if jsonschema.Draft202012Validator(schema["if"]).is_valid(out):
            for key, sub in schema["then"].get("properties", {}).items():
                if key not in out and isinstance(sub, Mapping) and "default" in sub:
                    out[key] = copy.deepcopy(sub["default"])


def _overrides_to_nested(overrides: Mapping | Iterable[str]) -> dict:
    """Overrides as nested dict; accepts nested dicts, dotted keys, or ``"a.b=value"`` strings."""
    nested: dict = {}
    if isinstance(overrides, Mapping):
        items = list(overrides.items())
    else:
        items = []
        for text in overrides:
            if "=" not in str(text):
                raise ConfigError(
                    f"overrides: {text!r} has no '=' — write key=value, e.g. mesh.refine=2"
                )
            key, raw = str(text).split("=", 1)
            try:
                value = yaml.load(raw, Loader=Loader) if raw.strip() else None
            except yaml.YAMLError:
                raise ConfigError(
                    f"overrides: {key.strip()}: {raw!r} is not a valid YAML value — quote it or fix the brackets"
                ) from None
            items.append((key.strip(), value))
    for key, value in items:
        parts = str(key).split(".")
        node = nested
        for part in parts[:-1]:
            if not isinstance(node.get(part), dict):
                node[part] = {}
            node = node[part]
        last = parts[-1]
        if isinstance(value, Mapping) and isinstance(node.get(last), dict):
            node[last] = deep_merge(node[last], value)
        else:
            node[last] = copy.deepcopy(value)
    return nested


# -------------------------------------------------------------------- schema-error translation
def _translate(error) -> list[tuple[list, str]]:
    """One jsonschema ValidationError -> list of (path, 'what — fix') without the label."""
    path = list(error.absolute_path)
    key = _last_key(path)
    sch = error.schema if isinstance(error.schema, Mapping) else {}
    val = error.instance
    v = error.validator
    out: list[tuple[list, str]] = []

    if "propertyNames" in error.schema_path:
        hint = sch.get("title") or f"match {sch.get('pattern', '')}"
        pattern = sch.get("pattern", "")
        out.append((path + [str(val)], f"name does not match {pattern} — rename it: {hint}"))
    elif v == "additionalProperties":
        allowed = list(sch.get("properties", {}))
        extras = [k for k in val if k not in sch.get("properties", {})
                  and not any(re.search(p, k) for p in sch.get("patternProperties", {}))]
        for extra in extras:
            guess = _suggest(extra, allowed)
            advice = f"did you mean {guess!r}?" if guess else "remove it or fix the spelling"
            out.append((path + [extra], f"unknown key — {advice} (allowed: {', '.join(allowed)})"))
    elif v == "required":
        props = sch.get("properties", {})
        for missing in error.validator_value:
            if missing in val:
                continue
            sub = props.get(missing, {})
            out.append((path + [missing], f"missing — add it: {_need_phrase(sub, missing)}"))
    elif v == "type":
        expected = error.validator_value
        expected = [expected] if isinstance(expected, str) else list(expected)
        exp_text = " or ".join(_EXPECTED.get(e, e) for e in expected)
        shown = _show(val) if not isinstance(val, (Mapping, list)) else _kind(val)
        msg = f"{shown} is {_kind(val)}, expected {exp_text} — {_fix_phrase(sch, key)}"
        if isinstance(val, str) and _text_of(val, expected):
            msg += (" (snakemake --config passes the values inside a mapping as text: give this one in a "
                    "config file added with --configfile)")
        out.append((path, msg))
    elif v in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        op = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}[v]
        out.append((path, f"{_show(val)} must be {op} {_fmt_num(error.validator_value)} — {_fix_phrase(sch, key)}"))
    elif v == "enum":
        choices = [str(c) for c in error.validator_value]
        guess = _suggest(val, choices) if isinstance(val, str) else None
        advice = f"did you mean {guess!r}?" if guess else "choose one of them"
        out.append((path, f"{_show(val)} is not allowed — {advice} (allowed: {', '.join(choices)})"))
    elif v == "pattern":
        title = sch.get("title") or f"text matching {error.validator_value}"
        example = f", e.g. {sch['default']!r}" if "default" in sch else ""
        out.append((path, f"{_show(val)} is not a valid {title} — fix the name{example}"))
    elif v in ("minItems", "maxItems"):
        n = len(val)
        lo, hi = sch.get("minItems"), sch.get("maxItems")
        need = f"exactly {lo}" if lo is not None and lo == hi else (
            f"at least {lo}" if v == "minItems" else f"at most {hi}")
        out.append((path, f"{_show(val)} has {n} item{'s' if n != 1 else ''}, needs {need} — {_fix_phrase(sch, key)}"))
    elif v == "minProperties":
        example = ""
        if isinstance(sch.get("default"), Mapping) and sch["default"]:
            first = next(iter(sch["default"]))
            example = f", e.g. {first}: {_show(sch['default'][first], 100)}"
        out.append((path, f"is empty — add at least {error.validator_value} entr{'y' if error.validator_value == 1 else 'ies'}{example}"))
    elif v == "minLength":
        out.append((path, f"{_show(val)} is empty — {_fix_phrase(sch, key)}"))
    else:  # keyword not used by the shipped schema: short generic line, never a raw dump
        message = str(error.message).splitlines()[0]
        if len(message) > 100:
            message = message[:97] + "..."
        out.append((path, f"{message} — see docs/config-reference.md"))
    return out


# ---------------------------------------------------------------------------- semantic checks
class _Skip(Exception):
    """A semantic check lacks valid input (already reported by the schema)."""


class _Checks:
    """Context for the semantic checks: the normalised config and the paths with schema errors."""

    def __init__(self, cfg: dict, bad: set[tuple], schema: Mapping):
        self.cfg = cfg
        self.bad = bad
        self.schema = schema
        self.problems: list[tuple[list, str]] = []

    def get(self, dotted: str) -> Any:
        parts = tuple(dotted.split("."))
        for n in range(1, len(parts) + 1):
            if parts[:n] in self.bad:
                raise _Skip
        node: Any = self.cfg
        for p in parts:
            if not isinstance(node, Mapping) or p not in node:
                raise _Skip
            node = node[p]
        return node

    def num(self, dotted: str) -> float:
        value = self.get(dotted)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _Skip
        return value

    def need(self, dotted: str) -> str:
        """'the <title> in <unit>, <range>' for a key, from the schema."""
        sub: Mapping | None = self.schema
        for part in dotted.split("."):
            sub = _subschema(sub or {}, part)
        return _need_phrase(sub or {}, dotted.rsplit(".", 1)[-1])

    def add(self, dotted: str | list, message: str) -> None:
        self.problems.append((dotted.split(".") if isinstance(dotted, str) else list(dotted), message))


def _check_materials(c: _Checks) -> None:
    try:
        materials = c.get("materials")
    except _Skip:
        return
    names = list(materials) if isinstance(materials, Mapping) else []
    for part in ("base", "rails", "carriages", "table"):
        try:
            name = c.get(f"rig.{part}.material")
        except _Skip:
            continue
        if isinstance(name, str) and name not in names:
            guess = _suggest(name, names)
            advice = f"did you mean {guess!r}?" if guess else f"use one of: {', '.join(names)} or add it to materials"
            c.add(f"rig.{part}.material", f"{name!r} is not in materials — {advice}")


def _check_geometry(c: _Checks) -> None:
    g = "rig."

    def rails_on_base():
        rl, bl = c.num(g + "rails.length_m"), c.num(g + "base.length_m")
        if rl > bl:
            c.add(g + "rails.length_m", f"{_fmt_num(rl)} is longer than the base ({_fmt_num(bl)} m) — shorten the rails or lengthen the base")

    def rails_across_base():
        s, rw, bw = c.num(g + "rails.spacing_m"), c.num(g + "rails.width_m"), c.num(g + "base.width_m")
        if s + rw > bw:
            c.add(g + "rails.spacing_m", f"spacing {_fmt_num(s)} + rail width {_fmt_num(rw)} = {_fmt_num(s + rw)} exceeds the base width {_fmt_num(bw)} — the rails must stand on the base; reduce spacing_m or widen the base")

    def carriages_apart_across():
        s, cw = c.num(g + "rails.spacing_m"), c.num(g + "carriages.width_m")
        if s < cw:
            c.add(g + "rails.spacing_m", f"{_fmt_num(s)} is less than the carriage width {_fmt_num(cw)} — carriages on the two rails would overlap; use spacing_m >= carriages.width_m")

    def carriages_apart_along():
        p, cl = c.num(g + "carriages.pitch_m"), c.num(g + "carriages.length_m")
        if p < cl:
            c.add(g + "carriages.pitch_m", f"{_fmt_num(p)} is less than the carriage length {_fmt_num(cl)} — the two carriages on a rail would overlap; use pitch_m >= carriages.length_m")

    def carriages_under_table_along():
        p, cl, tl = c.num(g + "carriages.pitch_m"), c.num(g + "carriages.length_m"), c.num(g + "table.length_m")
        if p + cl > tl:
            c.add(g + "carriages.pitch_m", f"pitch {_fmt_num(p)} + carriage length {_fmt_num(cl)} = {_fmt_num(p + cl)} exceeds the table length {_fmt_num(tl)} — the carriages must fit under the table; reduce pitch_m or lengthen the table")

    def carriages_under_table_across():
        s, cw, tw = c.num(g + "rails.spacing_m"), c.num(g + "carriages.width_m"), c.num(g + "table.width_m")
        if s + cw > tw:
            c.add(g + "rails.spacing_m", f"spacing {_fmt_num(s)} + carriage width {_fmt_num(cw)} = {_fmt_num(s + cw)} exceeds the table width {_fmt_num(tw)} — the carriages must fit under the table; reduce spacing_m or widen the table")

    def table_on_rails():
        pos, p, cl, rl = (c.num(g + "table.position_m"), c.num(g + "carriages.pitch_m"),
                          c.num(g + "carriages.length_m"), c.num(g + "rails.length_m"))
        half_span = (p + cl) / 2
        limit = rl / 2 - half_span
        if abs(pos) > limit + 1e-12:
            if limit < 0:
                c.add(g + "table.position_m", f"the carriage span {_fmt_num(p + cl)} is longer than the rails ({_fmt_num(rl)}) — lengthen the rails or reduce carriages.pitch_m")
            else:
                c.add(g + "table.position_m", f"{_fmt_num(pos)} moves the carriages off the rails — keep |position_m| <= {_fmt_num(round(limit, 9))} (half rail length minus half the carriage span)")

    def carriage_wraps_rail():
        cw, rw = c.num(g + "carriages.width_m"), c.num(g + "rails.width_m")
        flanks = c.get("joints.lateral_face") == "flanks"
        if cw < rw or (flanks and cw == rw):
            c.add(g + "carriages.width_m", f"{_fmt_num(cw)} is not wider than the rail ({_fmt_num(rw)}) — the carriage wraps the rail and must cover its top{' and flanks' if flanks else ''}; widen the carriage")

    def flank_contact_fits():
        if c.get("joints.lateral_face") != "flanks":
            return
        fh, gc, rh = (c.num(g + "carriages.flank_contact_height_m"), c.num(g + "carriages.ground_clearance_m"),
                      c.num(g + "rails.height_m"))
        if fh + gc > rh:
            c.add(g + "carriages.flank_contact_height_m", f"flank contact {_fmt_num(fh)} + ground clearance {_fmt_num(gc)} = {_fmt_num(fh + gc)} exceeds the rail height {_fmt_num(rh)} — the contact band must lie on the rail flank; reduce one of them")

    def carriage_above_rail():
        ch, rh = c.num(g + "carriages.height_m"), c.num(g + "rails.height_m")
        if ch <= rh:
            c.add(g + "carriages.height_m", f"{_fmt_num(ch)} does not reach above the rail top ({_fmt_num(rh)} above the base) — carriage height is measured from the base top; make it larger than rails.height_m")

    def clearance_below_rail_top():
        gc, rh = c.num(g + "carriages.ground_clearance_m"), c.num(g + "rails.height_m")
        if gc >= rh:
            c.add(g + "carriages.ground_clearance_m", f"{_fmt_num(gc)} is not below the rail height {_fmt_num(rh)} — the carriage's lower edge must lie beside the rail; reduce ground_clearance_m")

    def motor_patch_on_table():
        for dim, tkey in (("patch_width_m", "width_m"), ("patch_length_m", "length_m")):
            pv, tv = c.num(g + "motors." + dim), c.num(g + "table." + tkey)
            if pv > tv:
                c.add(g + "motors." + dim, f"{_fmt_num(pv)} exceeds the table {tkey[:-2]} {_fmt_num(tv)} — the motor mass is spread under the table; use {dim} <= table.{tkey}")

    def mounts_fit():
        if c.get(g + "support.kind") != "mounts":
            return
        inset, size = c.num(g + "support.mount_inset_m"), c.num(g + "support.mount_size_m")
        half = min(c.num(g + "base.length_m"), c.num(g + "base.width_m")) / 2
        if inset < size / 2:
            c.add(g + "support.mount_inset_m", f"{_fmt_num(inset)} is less than half the mount size ({_fmt_num(size / 2)}) — the inset is measured to the mount centre, so the pads would stick out of the base; use mount_inset_m >= mount_size_m / 2")
        elif inset + size / 2 > half:
            c.add(g + "support.mount_inset_m", f"inset {_fmt_num(inset)} + half the mount size {_fmt_num(size / 2)} = {_fmt_num(inset + size / 2)} exceeds half the smaller base side ({_fmt_num(half)}) — the four mount pads would overlap; reduce mount_inset_m or mount_size_m")

    checks = [rails_on_base, rails_across_base, carriages_apart_across, carriages_apart_along,
              carriages_under_table_along, carriages_under_table_across, table_on_rails,
              carriage_wraps_rail, flank_contact_fits, carriage_above_rail, clearance_below_rail_top,
              motor_patch_on_table, mounts_fit]
    for check in checks:
        try:
            check()
        except _Skip:
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


def _check_mesh(c: _Checks) -> None:
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
    except _Skip:
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
          f"{_fmt_num(h)} is too small (with refine: {refine}): about {_fmt_num(float(f'{n:.2g}'))} nodes, "
          f"above the limit of {_fmt_num(float(MAX_NODES))}"
          f" — use max_cell_size_m >= {_fmt_num(float(f'{good:.2g}'))} with refine: {refine}")


_DAMPING_PARAMS = {
    "modal": ("damping_ratio",),
    "rayleigh": ("alpha_per_s", "beta_s"),
    "joint": ("joint_loss_factor_s",),
    "measured": (),
}
"""Damping fields each harmonic.damping.model needs (as in jointid.response.damping; joint_energy_share is computed)."""

_DIRECTION_OF_NAME = {"normal": "y", "lateral": "x", "feed": "z"}


def _check_joints(c: _Checks) -> None:
    try:
        params = c.get("joints.parameters")
    except _Skip:
        return
    if not isinstance(params, Mapping):
        return
    seen_dir: dict[str, str] = {}
    for name, p in params.items():
        base = f"joints.parameters.{name}"
        try:
            lower, upper = c.num(base + ".lower"), c.num(base + ".upper")
            if lower > upper:
                c.add(base, f"lower {_fmt_num(lower)} >= upper {_fmt_num(upper)} — bounds are inverted; swap them")
            elif lower == upper:
                c.add(base, f"lower {_fmt_num(lower)} == upper {_fmt_num(upper)} — widen the bounds, or move it to joints.fixed to keep it constant")
        except _Skip:
            pass
        try:
            direction = c.get(base + ".direction")
        except _Skip:
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
    except _Skip:
        return
    if isinstance(fixed, Mapping):
        for name in fixed:
            if name in params:
                c.add(f"joints.fixed.{name}", "is also in joints.parameters — a stiffness is either identified or fixed; remove it from one of them")


def _states_and_datasets(c: _Checks) -> tuple[Mapping, Mapping] | None:
    """The ``states`` and ``datasets`` sections, or None when either is missing or malformed."""
    try:
        states, datasets = c.get("states"), c.get("datasets")
    except _Skip:
        return None
    if not isinstance(states, Mapping) or not isinstance(datasets, Mapping):
        return None
    return states, datasets


def _check_states(c: _Checks) -> None:
    sections = _states_and_datasets(c)
    if sections is None:
        return
    states, datasets = sections
    for dname, ds in datasets.items():
        if not isinstance(ds, Mapping) or not isinstance(ds.get("states"), list):
            continue
        for i, sname in enumerate(ds["states"]):
            if isinstance(sname, str) and sname not in states:
                guess = _suggest(sname, states)
                advice = f"did you mean {guess!r}?" if guess else f"use one of: {', '.join(states)}"
                c.add(["datasets", dname, "states", i], f"{sname!r} is not in states — {advice}")


def _n_identified(c: _Checks) -> int:
    params = c.get("joints.parameters")
    if not isinstance(params, Mapping) or not params:
        raise _Skip
    return len(params)


def _check_doe(c: _Checks) -> None:
    try:
        k = _n_identified(c)
        design = c.get("doe.design")
    except _Skip:
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
    except _Skip:
        pass


def _check_harmonic(c: _Checks) -> None:
    try:
        band = c.get("harmonic.band_Hz")
        if isinstance(band, list) and len(band) == 2 and all(
            isinstance(b, (int, float)) and not isinstance(b, bool) for b in band
        ):
            if band[0] >= band[1]:
                c.add("harmonic.band_Hz", f"{_show(band)} is not increasing — write [low, high]")
    except _Skip:
        pass
    try:
        point = c.get("harmonic.drive_point")
        if isinstance(point, str) and not _POINT_RE.match(point):  # normally caught by the schema
            c.add("harmonic.drive_point", f"{point!r} is not a measuring-point name — use T01..T18 (table) or B01..B18 (base)")
    except _Skip:
        pass
    try:
        model = c.get("harmonic.damping.model")
        damping = c.get("harmonic.damping")
    except _Skip:
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


def _check_solver(c: _Checks) -> None:
    try:
        if c.get("rig.support.kind") == "free" and c.num("solver.shift_Hz") == 0:
            c.add("solver.shift_Hz", "0 with rig.support.kind: free factorises a singular stiffness (rigid-body modes) — use a negative shift, e.g. -10")
    except _Skip:
        pass
    try:
        weights = c.get("identify.weights")
        if isinstance(weights, list) and weights and all(
            isinstance(w, (int, float)) and not isinstance(w, bool) and w == 0 for w in weights
        ):
            c.add("identify.weights", "all weights are 0 — give at least one positive weight, or [] for all 1")
    except _Skip:
        pass


_SEMANTIC_CHECKS = (_check_materials, _check_geometry, _check_mesh, _check_joints, _check_states,
                    _check_doe, _check_harmonic, _check_solver)


def _check_datasets(c: _Checks) -> None:
    """The measured datasets the run reads exist, and hold the states that use them.

    A state reads ``states.<s>.dataset`` (a name in ``datasets``, else a folder), else
    ``measurements.dataset``; every ``datasets.<n>.path`` is read by the diagnosis.  Folders are
    relative to the working directory (as in the workflow).  Only the state names of each
    ``modes.csv`` are read here; the full validation of a dataset stays with the stage reading it.
    """
    from jointid.data.dataset import modes_per_state

    sections = _states_and_datasets(c)
    if sections is None:
        return
    states, named = sections
    here = f"relative to the working directory {Path.cwd()}"

    def folder_problem(path: str) -> str | None:
        if Path(path).is_dir():
            return None
        return "is a file, not a folder" if Path(path).exists() else "is not an existing folder"

    for dname, ds in named.items():
        path = ds.get("path") if isinstance(ds, Mapping) else None
        if not isinstance(path, str) or ("datasets", str(dname), "path") in c.bad:
            continue
        problem = folder_problem(path)
        if problem:
            c.add(["datasets", dname, "path"], f"{path!r} {problem} ({here}) — give the folder that holds "
                  "the dataset's modes.csv and conditions.yaml")

    default_users = []
    by_state: dict[str, str] = {}
    for sname, state in states.items():
        if not isinstance(state, Mapping) or ("states", str(sname), "dataset") in c.bad:
            continue
        value = state.get("dataset")
        if value is None:
            default_users.append(sname)
            continue
        if not isinstance(value, str):
            continue
        if value in named:
            path = named[value].get("path") if isinstance(named[value], Mapping) else None
            if isinstance(path, str):
                by_state[sname] = path
            continue
        problem = folder_problem(value)
        if problem is None:
            by_state[sname] = value
            continue
        guess = _suggest(value, named)
        if guess:
            advice = f"did you mean {guess!r}?"
        elif named:
            advice = f"use one of the datasets {', '.join(named)} or the path of a dataset folder ({here})"
        else:
            advice = (f"register it under datasets ({value}: {{path: <folder>, states: [{sname}]}}) or give "
                      f"the path of a dataset folder ({here})")
        c.add(["states", sname, "dataset"], f"{value!r} is neither a name in datasets nor an existing folder — {advice}")

    if default_users:
        try:
            path = c.get("measurements.dataset")
        except _Skip:
            path = None
        if isinstance(path, str):
            problem = folder_problem(path)
            if problem:
                c.add("measurements.dataset", f"{path!r} {problem} ({here}; used by "
                      f"{', '.join(map(str, default_users))}) — give the folder that holds the measured "
                      "modes.csv and conditions.yaml, or run from the folder it is relative to")
            else:
                for sname in default_users:
                    by_state[sname] = path

    # states without modes in their dataset (a cheap look at modes.csv's state column)
    measured: dict[str, dict[str, int] | None] = {}

    def states_in(path: str) -> dict[str, int] | None:
        if path not in measured:
            measured[path] = modes_per_state(path) if Path(path).is_dir() else None
        return measured[path]

    for sname, path in by_state.items():
        found = states_in(path)
        if found is not None and sname not in found:
            guess = _suggest(sname, [f for f in found if f not in states])
            hint = f" (did you mean {guess!r}? rename the state)" if guess else ""
            c.add(["states", sname], f"dataset {path} has no modes of state {sname!r} in modes.csv (its states: "
                  f"{', '.join(found) or 'none'}){hint} — measure it there, or set states.{sname}.dataset to a "
                  "dataset that holds it")
    _check_mode_counts(c, {s: states_in(p).get(s) for s, p in by_state.items() if states_in(p)})
    for dname, ds in named.items():
        if not isinstance(ds, Mapping) or not isinstance(ds.get("path"), str) or not isinstance(ds.get("states"), list):
            continue
        found = states_in(ds["path"])
        if found is None:
            continue
        for i, sname in enumerate(ds["states"]):
            if isinstance(sname, str) and sname in states and sname not in found:
                c.add(["datasets", dname, "states", i], f"{sname!r} has no modes in {ds['path']}/modes.csv (its "
                      f"states: {', '.join(found) or 'none'}) — remove it from the list, or add its modes")


def _check_mode_counts(c: _Checks, counts: dict[str, int | None]) -> None:
    """One weight per measured mode, and enough model modes to pair them, before any solve runs."""
    counts = {s: n for s, n in counts.items() if n}
    if not counts:
        return
    try:
        weights = c.get("identify.weights")
        if isinstance(weights, list) and weights:
            wrong = {s: n for s, n in counts.items() if n != len(weights)}
            if wrong:
                c.add("identify.weights", f"{len(weights)} weights, but the datasets measure "
                      + ", ".join(f"{n} mode{'s' * (n != 1)} of {s}" for s, n in wrong.items())
                      + " — give one weight per measured mode, or [] for all 1")
    except _Skip:
        pass
    try:
        n_modes = c.get("solver.n_modes")
        most = max(counts.values())
        if isinstance(n_modes, int) and not isinstance(n_modes, bool) and n_modes < most:
            state = max(counts, key=counts.get)
            c.add("solver.n_modes", f"{n_modes} model modes cannot pair the {most} measured modes of {state} — "
                  f"use n_modes >= {most} (a few more, so that the pairing can skip modes the test did not see)")
    except _Skip:
        pass


# --------------------------------------------------------------------------------- public API
def check_config(cfg: Mapping, source: str = _DEFAULT_SOURCE, schema: Mapping | None = None,
                 *, check_datasets: bool = False) -> tuple[dict, list[str]]:
    """Fill defaults and validate ``cfg``; return ``(normalised config, problem lines)``.

    A key whose value is null counts as not given (its default applies): in a config file merged
    after another one, ``key: null`` removes the value the earlier file set.

    Parameters
    ----------
    cfg : mapping
        Raw configuration (e.g. Snakemake's ``config``); not modified.
    source : str
        Label that starts every problem line (the file name).
    schema : mapping, optional
        JSON-Schema; default :func:`load_schema`.
    check_datasets : bool
        Also check that the measured datasets the run reads (``states.<s>.dataset``,
        ``measurements.dataset``, ``datasets.<n>.path``) are existing folders, relative to the
        working directory, whose ``modes.csv`` holds the states that use them.  Off by default
        (the result then does not depend on the working directory); ``python -m jointid.config.core
        check`` and the Snakefile turn it on.

    Returns
    -------
    (dict, list of str)
        The configuration with defaults applied and numbers normalised (number keys as float,
        integer keys as int), and one line per problem (empty when valid).
    """
    import jsonschema

    schema = load_schema() if schema is None else schema
    if not isinstance(cfg, Mapping):
        return {}, [f"{source}: holds {_kind(cfg)}, not a mapping of sections — write key: value sections (materials:, rig:, mesh: ...)"]
    raw_problems: list[tuple[list, str]] = []
    normal = _normalise(cfg, schema, [], raw_problems)

    validator = jsonschema.Draft202012Validator(schema)
    reported: set[tuple] = {tuple(map(str, path)) for path, _ in raw_problems}
    for error in validator.iter_errors(normal):
        for path, message in _translate(error):
            if tuple(map(str, path)) not in reported:  # one schema line per key (e.g. type, not also enum)
                reported.add(tuple(map(str, path)))
                raw_problems.append((path, message))
    bad = {tuple(str(p) for p in path) for path, _ in raw_problems}
    checks = _Checks(normal, bad, schema)
    for check in _SEMANTIC_CHECKS + ((_check_datasets,) if check_datasets else ()):
        check(checks)
    raw_problems.extend(checks.problems)

    lines: list[str] = []
    for path, message in raw_problems:
        line = f"{source}: {_dotted(path)}: {message}"
        if line not in lines:
            lines.append(line)
    return normal, lines


def load_config(path_or_dict: str | os.PathLike | Mapping,
                overrides: Mapping | Iterable[str] | None = None,
                *, source: str | None = None, schema: Mapping | None = None,
                check_datasets: bool = False) -> dict:
    """Load, default and validate a configuration.

    Overrides merge deeply into the file; a null value removes the key the file set (see
    :func:`check_config`).

    Parameters
    ----------
    path_or_dict : path-like or mapping
        A YAML file, or an already loaded mapping (e.g. Snakemake's ``config``; numbers that a
        YAML 1.1 reader left as text, like ``'2.06e11'``, are converted).
    overrides : mapping or iterable of str, optional
        Applied on top before validation: a nested mapping (deep-merged), a mapping with dotted
        keys (``{"mesh.refine": 2}``) or ``"key=value"`` strings (value read as YAML).
    source : str, optional
        Label of the problem lines; default the path as given, or ``"config.yaml"`` for a mapping.
    schema : mapping, optional
        JSON-Schema; default :func:`load_schema`.
    check_datasets : bool
        Also check the measured dataset folders (see :func:`check_config`).

    Returns
    -------
    dict
        Validated configuration with all defaults filled in.

    Raises
    ------
    ConfigError
        With one line per problem, all problems together.
    """
    if isinstance(path_or_dict, Mapping):
        label = source or _DEFAULT_SOURCE
        raw = copy.deepcopy(dict(path_or_dict))
    else:
        label = source or str(path_or_dict)
        raw = read_yaml(Path(path_or_dict), label)
        if raw is None:
            raw = {}
    if overrides:
        if not isinstance(raw, Mapping):
            raise ConfigError(f"{label}: holds {_kind(raw)}, not a mapping of sections — write key: value sections")
        raw = deep_merge(dict(raw), _overrides_to_nested(overrides))
    cfg, problems = check_config(raw, source=label, schema=schema, check_datasets=check_datasets)
    if problems:
        raise ConfigError(problems)
    return cfg


def _canonical(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return _canonical(value.tolist())
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        if isinstance(value, float):
            if not math.isfinite(value):
                raise ConfigError(f"config: {value} cannot be hashed — use finite numbers")
            if value.is_integer() and abs(value) < 2**53:
                return int(value)
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise ConfigError(f"config: value of type {type(value).__name__} cannot be hashed — use YAML types only")


def config_hash(cfg: Mapping, keys: str | Iterable[str] | None = None) -> str:
    """Stable short hash of a configuration or of some of its sections.

    The hash is the first 12 hex digits of the SHA-256 of canonical JSON (sorted keys, no
    whitespace, integral floats written as integers so ``1`` and ``1.0`` hash alike).

    Parameters
    ----------
    cfg : mapping
        Configuration (normally from :func:`load_config`).
    keys : str or iterable of str, optional
        Dotted keys of the sections to hash (e.g. ``["rig", "mesh", "joints.parameters"]``);
        default the whole configuration.

    Returns
    -------
    str
        12 lower-case hex digits.
    """
    if keys is None:
        payload = _canonical(cfg)
    else:
        keys = [keys] if isinstance(keys, str) else list(keys)
        payload = {k: _canonical(section(cfg, k)) for k in keys}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]


def section(cfg: Mapping, *keys: str) -> Any:
    """Deep copy of a (sub)section, e.g. ``section(cfg, "rig", "base")`` or ``section(cfg, "rig.base")``.

    Raises
    ------
    ConfigError
        If a key is missing (with a spelling suggestion).
    """
    node: Any = cfg
    walked: list[str] = []
    for key in keys:
        for part in str(key).split("."):
            if not isinstance(node, Mapping) or part not in node:
                choices = list(node) if isinstance(node, Mapping) else []
                guess = _suggest(part, choices)
                advice = f"did you mean {guess!r}?" if guess else f"available: {', '.join(map(str, choices)) or 'none'}"
                raise ConfigError(f"config: {_dotted(walked + [part])}: no such section — {advice}")
            node = node[part]
            walked.append(part)
    return copy.deepcopy(node)


# ------------------------------------------------------------------------------ documentation
def _md(text: Any) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ").strip()


def _conditional_defaults(schema: Mapping) -> dict[str, tuple[Any, str]]:
    """Defaults set by ``then`` when ``if`` holds: {key: (default, 'if model: modal')}."""
    cond, then = schema.get("if"), schema.get("then")
    if not isinstance(cond, Mapping) or not isinstance(then, Mapping):
        return {}
    when = ", ".join(f"{k}: {v['const']}" for k, v in cond.get("properties", {}).items()
                     if isinstance(v, Mapping) and "const" in v)
    return {k: (v["default"], f"if {when}") for k, v in then.get("properties", {}).items()
            if isinstance(v, Mapping) and "default" in v}


def _doc_default(schema: Mapping, required: bool) -> str:
    if required:
        return "*required*"
    if "default" not in schema:
        return "—"
    if "x-when" in schema:
        return f"`{_doc_scalar(schema['default'])}` {schema['x-when']}"
    value = schema["default"]
    if isinstance(value, Mapping):
        if not value:
            return "`{}`"
        if all(not isinstance(v, (Mapping, list)) for v in value.values()):
            return ", ".join(f"`{k}: {_doc_scalar(v)}`" for k, v in value.items())
        return ", ".join(f"`{k}`" for k in value)
    if isinstance(value, list):
        return "`[" + ", ".join(_doc_scalar(v) for v in value) + "]`"
    return f"`{_doc_scalar(value)}`"


def _doc_scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e6:
        return f"{value:.1f}"
    if isinstance(value, (int, float)):
        return _fmt_num(value)
    return str(value)


def _doc_type(schema: Mapping) -> str:
    typ = schema.get("type", "any")
    if typ == "array":
        return f"list of {schema.get('items', {}).get('type', 'any')}"
    if typ == "object" and isinstance(schema.get("additionalProperties"), Mapping):
        return "map"
    return str(typ)


def _doc_allowed(schema: Mapping) -> str:
    parts = []
    if "enum" in schema:
        parts.append(", ".join(f"`{v}`" for v in schema["enum"]))
    if _bounds_text(schema):
        parts.append(_bounds_text(schema))
    if "pattern" in schema:
        parts.append(f"`{schema['pattern']}`")
    if "minLength" in schema:
        parts.append("not empty")
    if schema.get("type") == "array":
        lo, hi = schema.get("minItems"), schema.get("maxItems")
        if lo is not None and lo == hi:
            parts.append(f"{lo} items")
        elif lo:
            parts.append(f">= {lo} items")
        if _bounds_text(schema.get("items", {})):
            parts.append("each " + _bounds_text(schema["items"]))
    if schema.get("type") == "object":
        names = schema.get("propertyNames", {}).get("pattern")
        if names:
            parts.append(f"keys `{names}`")
        if schema.get("minProperties"):
            parts.append(f">= {schema['minProperties']} entries")
    return _md("; ".join(parts))


def _doc_rows(schema: Mapping, key: str, required: bool, rows: list[str]) -> None:
    """Append table rows for ``schema`` at dotted ``key`` (children instead of fixed-key objects)."""
    props = schema.get("properties") if schema.get("type") == "object" else None
    if props:
        req = set(schema.get("required", []))
        conditional = _conditional_defaults(schema)
        for name, sub in props.items():
            if name in conditional and "default" not in sub:
                sub = {**sub, "default": conditional[name][0], "x-when": conditional[name][1]}
            _doc_rows(sub, f"{key}.{name}", name in req, rows)
        return
    rows.append(f"| `{key}` | {_doc_type(schema)} | {_doc_default(schema, required)} | "
                f"{_doc_allowed(schema)} | {_md(schema.get('description', ''))} |")
    entry = schema.get("additionalProperties") if schema.get("type") == "object" else None
    if isinstance(entry, Mapping):
        _doc_rows(entry, f"{key}.<name>", False, rows)


def config_reference_markdown(schema: Mapping) -> str:
    """Markdown reference of all configuration keys, generated from the JSON-Schema.

    One table per top-level section with columns key, type, default, allowed values and
    description (with unit).

    Parameters
    ----------
    schema : mapping
        The config JSON-Schema (:func:`load_schema`).

    Returns
    -------
    str
        Markdown text ending in a newline; ``docs/config-reference.md`` holds exactly this.
    """
    out = [
        "# Configuration reference",
        "",
        "<!-- Generated from workflow/schemas/config.schema.yaml by "
        "`python -m jointid.config.core reference --output docs/config-reference.md`; do not edit by hand. -->",
        "",
        _md(schema.get("description", "")),
        "",
        "Every key may be omitted and then takes the default shown; *required* marks fields of map "
        "entries that must be given. `<name>` stands for a user-chosen entry name. Unknown keys are "
        "errors. An empty value (`null`, `~` or nothing after the colon) counts as omitted: in a config "
        "file merged after another (`snakemake --configfile config.yaml mine.yaml`, or `--set key=`) it "
        "removes the value the earlier file set, e.g. `harmonic: {damping: {model: rayleigh, "
        "alpha_per_s: 10, beta_s: 1e-6, damping_ratio: null}}` switches the shipped modal damping to "
        "Rayleigh. Check a file with `python -m jointid.config.core check config.yaml` (it also checks that "
        "the dataset folders exist, relative to the working directory).",
        "",
    ]
    for name, sub in schema.get("properties", {}).items():
        out.append(f"## `{name}`")
        out.append("")
        if sub.get("description"):
            out.append(_md(sub["description"]))
            out.append("")
        rows: list[str] = []
        _doc_rows(sub, name, False, rows)
        out.append("| Key | Type | Default | Allowed | Description |")
        out.append("|---|---|---|---|---|")
        out.extend(rows)
        out.append("")
    return "\n".join(out).rstrip("\n") + "\n"


# ------------------------------------------------------------------------------------------ CLI
def main(argv: list[str] | None = None) -> int:
    """Command line: ``check``, ``reference`` and ``hash``; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m jointid.config.core", description="jointid configuration tools")
    sub = parser.add_subparsers(dest="command", required=True)
    p_check = sub.add_parser("check", help="validate a config file")
    p_check.add_argument("config", nargs="?", default="config.yaml")
    p_check.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                         help="override a key (dotted), value read as YAML; repeatable")
    p_ref = sub.add_parser("reference", help="print the Markdown key reference")
    p_ref.add_argument("--output", help="write to this file instead of stdout")
    p_hash = sub.add_parser("hash", help="print the config hash (of some sections)")
    p_hash.add_argument("config", nargs="?", default="config.yaml")
    p_hash.add_argument("keys", nargs="*")
    args = parser.parse_args(argv)
    try:
        if args.command == "check":
            load_config(args.config, overrides=args.overrides or None, check_datasets=True)
            print(f"{args.config}: OK")
        elif args.command == "reference":
            text = config_reference_markdown(load_schema())
            if args.output:
                Path(args.output).write_text(text, encoding="utf-8")
            else:
                sys.stdout.write(text)
        elif args.command == "hash":
            print(config_hash(load_config(args.config), args.keys or None))
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
