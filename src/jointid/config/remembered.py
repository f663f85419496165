"""The Snakefile's validated configuration, remembered by what it depends on.

Every Snakemake start (a run, a dry run, the loop of docs/effects.md) validates the merged configuration:
the schema with its defaults (importing ``jsonschema``), each hypothesis's overrides, the semantic checks
and the dataset folders.  That is about 0.5 s of each start for a configuration that rarely changes.  The
validated configuration is a function of the configuration as given, this package's code and schema, the
working directory, the dataset folders' files and whether a mesh model's files exist; it is kept under a
digest of the first four (:func:`config_key`) with the folders' own digests
(:func:`jointid.data.checked.folder_key`) and the files' existence, which are compared at every start.

Only a configuration without problems is kept, and only one that JSON gives back equal (same types, same
order); any other is validated every time.  The answers live in ``validated-configs.json`` of the user's
cache folder (:mod:`jointid.usercache`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from jointid import usercache
from jointid.errors import ConfigError

__all__ = ["config_key", "validated_once"]

CACHE = "validated-configs"
"""The answers' file (:func:`jointid.usercache.cache_file`)."""

MAX_ENTRIES = 16
"""Most configurations remembered (the newest)."""


def config_key(raw: dict) -> str:
    """Digest of the configuration as given, the package's code and schema, and the working directory."""
    from jointid.config.schema import find_schema
    from jointid.version import code_digest

    h = hashlib.sha256(code_digest().encode())
    h.update(find_schema().read_bytes())
    h.update(os.getcwd().encode() + b"\0")
    h.update(json.dumps(raw, sort_keys=True, default=repr).encode())
    return h.hexdigest()


def validated_once(raw: dict, validate: Callable[[dict], dict]) -> dict:
    """``validate(raw)`` (which raises on a problem), or the configuration it gave for the same inputs before."""
    from jointid.data import checked

    try:
        key = config_key(raw)
    except (OSError, TypeError, ValueError, ConfigError):  # not digestible, no schema: validated as always
        key = None
    hit = usercache.lookup(CACHE, key) if key else None
    if isinstance(hit, dict) and _unchanged(hit):
        try:
            return json.loads(hit["config"])
        except (KeyError, TypeError, ValueError):
            pass
    with checked.recording() as folders:
        cfg = validate(raw)
    try:
        text = json.dumps(cfg)
        same = json.loads(text) == cfg
    except (TypeError, ValueError):
        same = False
    if key and same:
        try:
            entry = {"config": text, "folders": {f: checked.folder_key(f) for f in sorted(folders)},
                     "files": {f: Path(f).is_file() for f in _mesh_files(cfg)}}
        except OSError:
            return cfg
        usercache.remember(CACHE, key, entry, MAX_ENTRIES)
    return cfg


def _unchanged(hit: dict) -> bool:
    """The dataset folders and the mesh files of a remembered validation are as they were."""
    from jointid.data.checked import folder_key

    try:
        return all(folder_key(f) == k for f, k in hit["folders"].items()) and \
            all(Path(f).is_file() == bool(v) for f, v in hit["files"].items())
    except (OSError, KeyError, TypeError, AttributeError):
        return False


def _mesh_files(cfg: dict) -> list[str]:
    """The files a mesh model names (their existence is checked: :mod:`jointid.config.checks`)."""
    model = cfg.get("model") or {}
    if model.get("kind") != "mesh":
        return []
    return [str(model[k]) for k in ("path", "points") if model.get(k)]
