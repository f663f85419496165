"""Config handling inside the Snakefile: validate once at start, hand sections to rules."""

from __future__ import annotations

import copy
import os
import sys

from jointid.errors import ConfigError


def validated(config: dict) -> dict:
    """Validate (and fill defaults of) the Snakemake config; on error print the lines and exit 1.

    Snakemake has already merged the ``--configfile`` files (deeply, later files win; a ``null``
    there survives and removes the key, as in :func:`jointid.config.core.check_config`).  The measured
    dataset folders are checked too (relative to the working directory, as the rules read them),
    so a misnamed dataset stops the run here instead of as a missing input or a stale result.
    """
    from jointid.config.core import load_config

    try:
        return load_config(dict(config), check_datasets=True)
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        sys.exit(1)


def sections(config: dict, *names: str) -> dict:
    """A deep copy of the named parts of ``config`` (for ``params: cfg=``), nested as in ``config``.

    A name is a top-level section (``"rig"``) or a dotted path to a key inside one
    (``"harmonic.band_Hz"``, ``"states.power_on"``): a rule then depends on that key only, so
    changing another key of the section does not rerun it.  Names that are absent are skipped.

    Examples
    --------
    >>> sections({"a": {"x": 1, "y": 2}, "b": 3}, "a.x", "b")
    {'a': {'x': 1}, 'b': 3}
    """
    out: dict = {}
    for name in names:
        parts = name.split(".")
        node = config
        try:
            for p in parts:
                node = node[p]
        except (KeyError, TypeError):
            continue
        dest = out
        for p in parts[:-1]:
            dest = dest.setdefault(p, {})
        dest[parts[-1]] = copy.deepcopy(node)
    return out


def merged(*cfgs: dict) -> dict:
    """Deep union of several rules' config parts (later ones win on conflicting leaves).

    Used for the provenance of a result that depends on a chain of rules: the union of the parts
    every rule of the chain takes.
    """
    out: dict = {}
    for cfg in cfgs:
        _merge_into(out, cfg)
    return out


def _merge_into(dest: dict, src: dict) -> None:
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(dest.get(k), dict):
            _merge_into(dest[k], v)
        else:
            dest[k] = copy.deepcopy(v)


def registered_datasets(config: dict) -> dict:
    """The datasets to diagnose: those under `datasets:`, else the measured dataset of the run.

    Without a `datasets:` block the folder `measurements.dataset` (the paper's data by default) is
    diagnosed under its folder name, with the states that use it.
    """
    named = dict(config.get("datasets") or {})
    if named:
        return named
    path = config["measurements"]["dataset"]
    states = [s for s, c in config["states"].items() if not c.get("dataset")]
    name = os.path.basename(os.path.normpath(path))
    if not states or not name.isidentifier():
        return {}
    return {name: {"path": path, "states": states}}
