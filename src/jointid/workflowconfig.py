"""Config handling inside the Snakefile: validate once at start, hand sections to rules."""

from __future__ import annotations

import copy
import sys

from .errors import ConfigError


def validated(config: dict) -> dict:
    """Validate (and fill defaults of) the Snakemake config; on error print the lines and exit 1."""
    from .config import load_config

    try:
        return load_config(dict(config))
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        sys.exit(1)


def sections(config: dict, *names: str) -> dict:
    """A deep copy of the named top-level sections (for ``params: cfg=``)."""
    return {n: copy.deepcopy(config[n]) for n in names if n in config}
