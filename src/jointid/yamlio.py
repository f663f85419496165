"""YAML in jointid: one loader (YAML 1.2 numbers, duplicate keys flagged), one deep merge, one reader.

PyYAML follows YAML 1.1, where ``2.0e8`` is a *string*; every config, truth or conditions file of
jointid is read through :class:`Loader` so that it is a float, and through :func:`read_yaml` so that a
syntax error or a duplicate key is one :class:`~jointid.errors.ConfigError` line naming the file.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from jointid.errors import ConfigError


class Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """Safe YAML loader that reads ``1e11`` / ``2.0e8`` as floats (YAML 1.2) and flags duplicate keys.

    PyYAML follows YAML 1.1, where ``2.0e8`` (no sign in the exponent) is a *string*.  The parser is
    libyaml's where PyYAML has it (about ten times faster on the config schema), else PyYAML's own.
    """

    def __init__(self, stream):
        super().__init__(stream)
        self.duplicates: list[tuple[int, str]] = []

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *anchor' may be overridden
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                if key in seen:
                    self.duplicates.append((key_node.start_mark.line + 1, str(key)))
                seen.add(key)
            except TypeError:  # unhashable key: let PyYAML report it
                pass
        return super().construct_mapping(node, deep=deep)


_FLOAT_12 = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))

# strings that a YAML 1.1 reader (Snakemake's) leaves as text although they are numbers
_NUMERIC_STR = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


def number_from_text(value: Any) -> float | None:
    """The number spelt by ``value`` if it is text that a YAML 1.1 reader left as a string, else None.

    PyYAML (and so Snakemake and ``yaml.safe_load``) reads ``1e3``, ``2.0e8`` and ``1e+3`` as
    strings; this is the one rule by which jointid accepts them (and quoted numbers such as
    ``'1000'``) where a number is expected: decimal digits, optional point, optional exponent.
    Non-finite spellings (``inf``, ``nan``) are not numbers here; ``'1e999'`` gives ``inf``, which
    the caller reports as not finite.
    """
    if isinstance(value, str) and _NUMERIC_STR.match(value):
        return float(value)
    return None


def read_yaml(path: Path, label: str) -> Any:
    """Read a YAML file; syntax errors and duplicate keys become ConfigError lines."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{label}: file not found — pass the path of an existing config file") from None
    except OSError as exc:
        raise ConfigError(f"{label}: cannot be read ({exc.strerror}) — check the path and permissions") from None
    loader = Loader(text)
    try:
        data = loader.get_single_data()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{label}:{mark.line + 1}" if mark is not None else label
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(
            f"{where}: YAML syntax error ({problem}) — check indentation (spaces, no tabs), colons and brackets"
        ) from None
    finally:
        loader.dispose()
    if loader.duplicates:
        raise ConfigError(
            [
                f"{label}:{line}: {key}: duplicate key — keep only one (YAML would silently use the last)"
                for line, key in loader.duplicates
            ]
        )
    return data


def deep_merge(base: Mapping, update: Mapping | None) -> dict:
    """Deep merge ``update`` into a copy of ``base`` (mappings merge, everything else replaces).

    Examples
    --------
    >>> deep_merge({"a": {"x": 1, "y": 2}, "b": 1}, {"a": {"y": 3}, "c": 4})
    {'a': {'x': 1, 'y': 3}, 'b': 1, 'c': 4}
    """
    out = copy.deepcopy(dict(base))
    for key, value in (update or {}).items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def read_merged(paths) -> dict:
    """The YAML files ``paths`` read with :func:`read_yaml` and deep-merged in order (later files win)."""
    cfg: dict = {}
    for p in paths:
        cfg = deep_merge(cfg, read_yaml(Path(p), str(p)) or {})
    return cfg
