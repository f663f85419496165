"""The configuration JSON-Schema, shipped inside the package, and the defaults it fills in.

``schema.yaml`` next to this module is the single source of the keys, types, ranges, defaults and
descriptions (``docs/config-reference.md`` is generated from it).  It is read with
:mod:`importlib.resources`, so an installed jointid validates a config anywhere, not only inside
a source checkout; the environment variable ``JOINTID_SCHEMA`` may name another schema file.
:func:`normalise` fills the defaults and turns numbers given as text into numbers before the
schema validation.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import re
from collections.abc import Callable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from jointid.config.messages import fmt_num
from jointid.errors import ConfigError
from jointid.yamlio import number_from_text, read_yaml

__all__ = [
    "SCHEMA_ENV",
    "SCHEMA_FILE",
    "SCHEMA_PACKAGE",
    "find_schema",
    "load_schema",
    "normalise",
    "subschema",
]

SCHEMA_PACKAGE = "jointid.config"
SCHEMA_FILE = "schema.yaml"
"""The schema is the resource ``SCHEMA_FILE`` of the package ``SCHEMA_PACKAGE``."""
SCHEMA_ENV = "JOINTID_SCHEMA"
_IN_CHECKOUT = "src/jointid/config/schema.yaml"  # where a source checkout holds it (for messages)


# ------------------------------------------------------------------------------------- schema
def find_schema() -> Path:
    """Locate the config schema: ``schema.yaml`` of the package :mod:`jointid.config`.

    The file named by the environment variable ``JOINTID_SCHEMA`` takes precedence.  The
    working directory plays no part, so an installed jointid finds its schema from anywhere.

    Returns
    -------
    Path
        Absolute path of the schema file.

    Raises
    ------
    ConfigError
        If ``JOINTID_SCHEMA`` names a missing file or the package lacks its schema.
    """
    env = os.environ.get(SCHEMA_ENV)
    if env:
        path = Path(env).expanduser()
        if not path.is_file():
            raise ConfigError(
                f"{SCHEMA_ENV}={env}: schema file not found — point {SCHEMA_ENV} to "
                f"{_IN_CHECKOUT} of a jointid checkout, or unset it"
            )
        return path.resolve()
    resource = resources.files(SCHEMA_PACKAGE) / SCHEMA_FILE
    if isinstance(resource, Path) and resource.is_file():
        return resource.resolve()
    raise ConfigError(
        f"{resource}: jointid config schema missing from the installed package — reinstall jointid "
        f"(its wheel ships {SCHEMA_PACKAGE.replace('.', '/')}/{SCHEMA_FILE}) or set "
        f"{SCHEMA_ENV}=/path/to/schema.yaml"
    )


@functools.lru_cache(maxsize=8)
def _load_schema_cached(path: str, mtime: float) -> dict:
    data = read_yaml(Path(path), path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: not a JSON-Schema mapping — restore {_IN_CHECKOUT} from git")
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


# ------------------------------------------------------------------ defaults and normalisation
def default(key: str) -> Any:
    """The schema's default of the dotted config key ``key`` (e.g. ``"solver.method"``): where the typed
    options (:mod:`jointid.config.typed`) need a default, they take it from here, so that it lives in the
    schema alone.  A key whose default holds only under a condition (``if``/``then``, as
    ``harmonic.damping.damping_ratio``'s for the modal damping model) takes that one.  Raises KeyError for a
    key without a default."""
    node: Mapping | None = load_schema()
    parent: Mapping | None = None
    part = key
    for part in key.split("."):
        parent, node = node, (subschema(node, part) if node is not None else None)
    if node is None or "default" not in node:
        then = (parent or {}).get("then")
        node = then.get("properties", {}).get(part) if isinstance(then, Mapping) else None
    if node is None or "default" not in node:
        raise KeyError(f"schema.yaml gives no default for {key}")
    return copy.deepcopy(node["default"])


def given(section: Mapping | None, key: str, dotted: str) -> Any:
    """``section[key]`` where the section gives it, else the schema's :func:`default` of the dotted key
    ``dotted`` (a rule gets only the keys it hashes; the typed options fill the rest from here)."""
    section = section or {}
    return section[key] if key in section else default(dotted)


def field_default(key: str, convert: Callable[[Any], Any] = lambda v: v):
    """A dataclass field whose default is the schema's :func:`default` of ``key`` (``convert``-ed): the typed
    options' defaults live in the schema alone."""
    from dataclasses import field

    return field(default_factory=lambda: convert(default(key)))


def subschema(schema: Mapping, key: str) -> Mapping | None:
    """The schema of ``key`` inside an object ``schema`` (properties, patterns, then map entries)."""
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


def normalise(value: Any, schema: Mapping | None, path: list, problems: list[tuple[list, str]]) -> Any:
    """Fill defaults, coerce numeric text and int/float per schema; note non-finite numbers.

    Returns a new value (plain dicts/lists); the input is not modified.
    """
    schema = schema or {}
    types = _types(schema)
    if isinstance(value, Mapping):
        out = {str(k) if not isinstance(k, str) else k: v for k, v in value.items()}
        # an empty value (null) counts as not given: a later config file removes a key an earlier one set
        out = {k: v for k, v in out.items() if not _unset(v, subschema(schema, k))}
        if "object" in types:
            _fill_defaults(out, schema)
        return {k: normalise(v, subschema(schema, k), path + [k], problems) for k, v in out.items()}
    if isinstance(value, (list, tuple)):
        items = schema.get("items") if isinstance(schema.get("items"), Mapping) else None
        return [normalise(v, items, path + [i], problems) for i, v in enumerate(value)]
    if hasattr(value, "item") and callable(value.item) and not isinstance(value, (str, bytes)):
        try:  # numpy scalar
            value = value.item()
        except (TypeError, ValueError):
            pass
    if types & {"number", "integer"} and (number := number_from_text(value)) is not None:
        value = number
    if isinstance(value, float) and not math.isfinite(value):
        problems.append((path, f"{fmt_num(value)} is not a finite number — give a finite value"))
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
        import jsonschema  # heavy (~0.1 s): config_hash and section users never validate

        if jsonschema.Draft202012Validator(schema["if"]).is_valid(out):
            for key, sub in schema["then"].get("properties", {}).items():
                if key not in out and isinstance(sub, Mapping) and "default" in sub:
                    out[key] = copy.deepcopy(sub["default"])
