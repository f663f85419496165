"""Problem lines of the configuration: jsonschema errors and values turned into user words.

Every problem is one line ``<file>: <dotted.key>: <what> — <how to fix>``; this module writes the
*what* and *how to fix* parts: numbers shown short and exact (:func:`fmt_num`), the unit spelt out
from the key's unit suffix, the allowed range (:func:`bounds_text`), a spelling suggestion
(:func:`suggest`), and one line per :class:`jsonschema.ValidationError` (:func:`translate`).
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

import yaml

__all__ = [
    "bounds_text",
    "dotted",
    "fix_phrase",
    "fmt_num",
    "kind",
    "need_phrase",
    "show",
    "suggest",
    "translate",
]

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


# ----------------------------------------------------------------------------------- formatting
def fmt_num(x: Any) -> str:
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


def show(value: Any, limit: int = 60) -> str:
    """Value as shown in a problem line."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif value is None:
        text = "null"
    elif isinstance(value, (int, float)):
        text = fmt_num(value)
    elif isinstance(value, str):
        text = repr(value)
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(show(v, limit) for v in value) + "]"
    elif isinstance(value, Mapping):
        text = "{" + ", ".join(f"{k}: {show(v, limit)}" for k, v in value.items()) + "}"
    else:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _text_of(text: str, expected: list[str]) -> bool:
    """Whether ``text`` spells a value of one of the ``expected`` JSON-schema types (e.g. 'true', '8')."""
    try:
        val = yaml.safe_load(text)
    except yaml.YAMLError:
        return False
    kinds = {"boolean": lambda v: isinstance(v, bool),
             "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
             "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)}
    return any(kinds.get(e, lambda v: False)(val) for e in expected)


def kind(value: Any) -> str:
    """What ``value`` is, in user words: 'a number', 'text', 'a list' ..."""
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


def dotted(parts: Iterable[Any]) -> str:
    """Key path as written in a problem line: ``rig.base.length_m``, ``identify.weights[2]``."""
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


def bounds_text(schema: Mapping) -> str:
    """The range a leaf schema allows, e.g. ``'> 0 and <= 0.5'`` ('' when unbounded)."""
    lo = hi = ""
    if "exclusiveMinimum" in schema:
        lo = f"> {fmt_num(schema['exclusiveMinimum'])}"
    elif "minimum" in schema:
        lo = f">= {fmt_num(schema['minimum'])}"
    if "exclusiveMaximum" in schema:
        hi = f"< {fmt_num(schema['exclusiveMaximum'])}"
    elif "maximum" in schema:
        hi = f"<= {fmt_num(schema['maximum'])}"
    return " and ".join(t for t in (lo, hi) if t)


def _has_bounds(schema: Mapping) -> tuple[bool, bool]:
    lo = "minimum" in schema or "exclusiveMinimum" in schema
    hi = "maximum" in schema or "exclusiveMaximum" in schema
    return lo, hi


def fix_phrase(schema: Mapping, key: str) -> str:
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
            text += f" ({bounds_text(schema)})"
        elif typ == "integer" and has_lo:
            text += f" {bounds_text(schema)}"
        return text
    if typ == "array":
        text = f"give the {title} as a list"
        if unit:
            text += f" in {unit}"
        if "default" in schema:
            text += f", e.g. {show(schema['default'])}"
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


def need_phrase(schema: Mapping, key: str) -> str:
    """'the <title> in <unit>, one of ...' describing a missing value."""
    text = "the " + (schema.get("title") or key.replace("_", " "))
    unit = _unit_words(key)
    if unit and schema.get("type") == "number":
        text += f" in {unit}"
    if "enum" in schema:
        text += ", one of " + ", ".join(str(v) for v in schema["enum"])
    elif bounds_text(schema):
        text += f", {bounds_text(schema)}"
    return text


def suggest(word: str, choices: Iterable[str]) -> str | None:
    """Closest choice (difflib), else the only choice that starts with ``word``; None if neither."""
    choices = [str(c) for c in choices]
    match = difflib.get_close_matches(str(word), choices, n=1, cutoff=0.6)
    if match:
        return match[0]
    prefixed = [c for c in choices if len(str(word)) >= 2 and c.lower().startswith(str(word).lower())]
    return prefixed[0] if len(prefixed) == 1 else None


# -------------------------------------------------------------------- schema-error translation
def translate(error) -> list[tuple[list, str]]:
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
            guess = suggest(extra, allowed)
            advice = f"did you mean {guess!r}?" if guess else "remove it or fix the spelling"
            out.append((path + [extra], f"unknown key — {advice} (allowed: {', '.join(allowed)})"))
    elif v == "required":
        props = sch.get("properties", {})
        for missing in error.validator_value:
            if missing in val:
                continue
            sub = props.get(missing, {})
            out.append((path + [missing], f"missing — add it: {need_phrase(sub, missing)}"))
    elif v == "type":
        expected = error.validator_value
        expected = [expected] if isinstance(expected, str) else list(expected)
        exp_text = " or ".join(_EXPECTED.get(e, e) for e in expected)
        shown = show(val) if not isinstance(val, (Mapping, list)) else kind(val)
        msg = f"{shown} is {kind(val)}, expected {exp_text} — {fix_phrase(sch, key)}"
        if isinstance(val, str) and _text_of(val, expected):
            msg += (" (snakemake --config passes the values inside a mapping as text: give this one in a "
                    "config file added with --configfile)")
        out.append((path, msg))
    elif v in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        op = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}[v]
        out.append((path, f"{show(val)} must be {op} {fmt_num(error.validator_value)} — {fix_phrase(sch, key)}"))
    elif v == "enum":
        choices = [str(c) for c in error.validator_value]
        guess = suggest(val, choices) if isinstance(val, str) else None
        advice = f"did you mean {guess!r}?" if guess else "choose one of them"
        out.append((path, f"{show(val)} is not allowed — {advice} (allowed: {', '.join(choices)})"))
    elif v == "pattern":
        title = sch.get("title") or f"text matching {error.validator_value}"
        example = f", e.g. {sch['default']!r}" if "default" in sch else ""
        out.append((path, f"{show(val)} is not a valid {title} — fix the name{example}"))
    elif v in ("minItems", "maxItems"):
        n = len(val)
        lo, hi = sch.get("minItems"), sch.get("maxItems")
        need = f"exactly {lo}" if lo is not None and lo == hi else (
            f"at least {lo}" if v == "minItems" else f"at most {hi}")
        out.append((path, f"{show(val)} has {n} item{'s' if n != 1 else ''}, needs {need} — {fix_phrase(sch, key)}"))
    elif v == "minProperties":
        example = ""
        if isinstance(sch.get("default"), Mapping) and sch["default"]:
            first = next(iter(sch["default"]))
            example = f", e.g. {first}: {show(sch['default'][first], 100)}"
        out.append((path, f"is empty — add at least {error.validator_value} entr{'y' if error.validator_value == 1 else 'ies'}{example}"))
    elif v == "minLength":
        out.append((path, f"{show(val)} is empty — {fix_phrase(sch, key)}"))
    else:  # keyword not used by the shipped schema: short generic line, never a raw dump
        message = str(error.message).splitlines()[0]
        if len(message) > 100:
            message = message[:97] + "..."
        out.append((path, f"{message} — see docs/config-reference.md"))
    return out
