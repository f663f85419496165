"""The Markdown reference of all configuration keys, generated from the schema.

``docs/config-reference.md`` holds exactly :func:`config_reference_markdown` of the shipped schema;
regenerate it with ``python -m jointid.config reference --output docs/config-reference.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from jointid.config.messages import bounds_text, fmt_num

__all__ = ["config_reference_markdown"]


def _md(text: Any) -> str:
    """``text`` as one Markdown table cell (pipes escaped, one line)."""
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
        return fmt_num(value)
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
    if bounds_text(schema):
        parts.append(bounds_text(schema))
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
        if bounds_text(schema.get("items", {})):
            parts.append("each " + bounds_text(schema["items"]))
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
        "<!-- Generated from src/jointid/config/schema.yaml by "
        "`python -m jointid.config reference --output docs/config-reference.md`; do not edit by hand. -->",
        "",
        _md(schema.get("description", "")),
        "",
        "Every key may be omitted and then takes the default shown; *required* marks fields of map "
        "entries that must be given. `<name>` stands for a user-chosen entry name. Unknown keys are "
        "errors. An empty value (`null`, `~` or nothing after the colon) counts as omitted: in a config "
        "file merged after another (`snakemake --configfile config.yaml mine.yaml`, or `--set key=`) it "
        "removes the value the earlier file set, e.g. `harmonic: {damping: {model: rayleigh, "
        "alpha_per_s: 10, beta_s: 1e-6, damping_ratio: null}}` switches the shipped modal damping to "
        "Rayleigh. Check a file with `python -m jointid.config check config.yaml` (it also checks that "
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
