"""Config handling inside the Snakefile: validate once at start, hand sections to rules."""

from __future__ import annotations

import copy
import sys

from jointid.config.load import load_config
from jointid.errors import ConfigError
from jointid.yamlio import deep_merge

__all__ = ["merged", "sections", "validated"]


def validated(config: dict) -> dict:
    """Validate (and fill defaults of) the Snakemake config; on error print the lines and exit 1.

    Snakemake has already merged the ``--configfile`` files (deeply, later files win; a ``null``
    there survives and removes the key, as in :func:`jointid.config.load.check_config`).  The measured
    dataset folders are checked too (relative to the working directory, as the rules read them),
    so a misnamed dataset stops the run here instead of as a missing input or a stale result.
    """
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

    Examples
    --------
    >>> merged({"a": {"x": 1}, "b": 1}, {"a": {"y": 2}, "b": 2})
    {'a': {'x': 1, 'y': 2}, 'b': 2}
    """
    out: dict = {}
    for cfg in cfgs:
        out = deep_merge(out, cfg)
    return out
