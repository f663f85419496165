"""Load and validate a configuration: the entry points :func:`load_config` and :func:`check_config`.

A configuration is read (YAML 1.2 numbers, see :mod:`jointid.yamlio`), overrides are merged in,
defaults are filled from the schema (:mod:`jointid.config.schema`), the schema is validated and its
errors translated (:mod:`jointid.config.messages`), and the semantic checks run
(:mod:`jointid.config.checks`, :mod:`jointid.config.rig`, :mod:`jointid.config.datasets`).  All
problems are collected and raised together as one :class:`jointid.errors.ConfigError`, one line
each::

    config.yaml: rig.base.length_m: -1.1 must be > 0 — give the base length in metres
"""

from __future__ import annotations

import copy
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from jointid.config.checks import (Checks, check_doe, check_harmonic, check_joints, check_materials, check_model,
                                   check_run, check_solver)
from jointid.config.datasets import check_dataset_folders, check_states
from jointid.config.messages import dotted, kind, suggest, translate
from jointid.config.rig import check_geometry, check_mesh
from jointid.config.schema import load_schema, normalise
from jointid.errors import ConfigError
from jointid.yamlio import Loader, deep_merge, read_yaml

__all__ = ["DEFAULT_SOURCE", "SEMANTIC_CHECKS", "check_config", "load_config", "section"]

DEFAULT_SOURCE = "config.yaml"
"""Label of the problem lines of a configuration given as a mapping."""

SEMANTIC_CHECKS = (check_materials, check_geometry, check_mesh, check_joints, check_states,
                   check_doe, check_harmonic, check_solver, check_model, check_run)
"""The semantic checks :func:`check_config` always runs, in the order their problems are reported."""


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


# --------------------------------------------------------------------------------- public API
def check_config(cfg: Mapping, source: str = DEFAULT_SOURCE, schema: Mapping | None = None,
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
        (the result then does not depend on the working directory); ``python -m jointid.config
        check`` and the Snakefile turn it on.

    Returns
    -------
    (dict, list of str)
        The configuration with defaults applied and numbers normalised (number keys as float,
        integer keys as int), and one line per problem (empty when valid).
    """
    import jsonschema  # heavy (~0.1 s): config_hash and section users never validate

    schema = load_schema() if schema is None else schema
    if not isinstance(cfg, Mapping):
        return {}, [f"{source}: holds {kind(cfg)}, not a mapping of sections — write key: value sections (materials:, rig:, mesh: ...)"]
    raw_problems: list[tuple[list, str]] = []
    normal = normalise(cfg, schema, [], raw_problems)

    validator = jsonschema.Draft202012Validator(schema)
    reported: set[tuple] = {tuple(map(str, path)) for path, _ in raw_problems}
    for error in validator.iter_errors(normal):
        for path, message in translate(error):
            if tuple(map(str, path)) not in reported:  # one schema line per key (e.g. type, not also enum)
                reported.add(tuple(map(str, path)))
                raw_problems.append((path, message))
    bad = {tuple(str(p) for p in path) for path, _ in raw_problems}
    checks = Checks(normal, bad, schema)
    for check in SEMANTIC_CHECKS + ((check_dataset_folders,) if check_datasets else ()):
        check(checks)
    raw_problems.extend(checks.problems)

    lines: list[str] = []
    for path, message in raw_problems:
        line = f"{source}: {dotted(path)}: {message}"
        if line not in lines:
            lines.append(line)
    if not lines:  # the hypotheses are checked on a valid configuration (else each repeats its problems)
        lines += _hypothesis_problems(normal, source, schema)
    return normal, lines


def _hypothesis_problems(normal: Mapping, source: str, schema: Mapping) -> list[str]:
    """Each reconstruction hypothesis's overrides merged into the configuration must validate too."""
    out = []
    hyps = normal.get("hypotheses") if isinstance(normal, Mapping) else None
    for name, hyp in (hyps or {}).items() if isinstance(hyps, Mapping) else ():
        over = hyp.get("overrides") if isinstance(hyp, Mapping) else None
        if not isinstance(over, Mapping) or not over:
            continue
        if "hypotheses" in over:
            out.append(f"{source}: hypotheses.{name}.overrides.hypotheses: a hypothesis cannot override the "
                       "hypotheses — remove that key")
            continue
        base = {k: v for k, v in normal.items() if k != "hypotheses"}
        _, probs = check_config(deep_merge(copy.deepcopy(base), copy.deepcopy(dict(over))),
                                source=f"{source}: hypotheses.{name}.overrides", schema=schema)
        out += probs
    return out


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
        label = source or DEFAULT_SOURCE
        raw = copy.deepcopy(dict(path_or_dict))
    else:
        label = source or str(path_or_dict)
        raw = read_yaml(Path(path_or_dict), label)
        if raw is None:
            raw = {}
    if overrides:
        if not isinstance(raw, Mapping):
            raise ConfigError(f"{label}: holds {kind(raw)}, not a mapping of sections — write key: value sections")
        raw = deep_merge(dict(raw), _overrides_to_nested(overrides))
    cfg, problems = check_config(raw, source=label, schema=schema, check_datasets=check_datasets)
    if problems:
        raise ConfigError(problems)
    return cfg


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
                guess = suggest(part, choices)
                advice = f"did you mean {guess!r}?" if guess else f"available: {', '.join(map(str, choices)) or 'none'}"
                raise ConfigError(f"config: {dotted(walked + [part])}: no such section — {advice}")
            node = node[part]
            walked.append(part)
    return copy.deepcopy(node)
