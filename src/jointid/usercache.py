"""Small answers remembered between runs in the user's cache folder (a shortcut, never a source of truth).

Each kind of answer is one JSON file, ``$JOINTID_CACHE_DIR/<name>.json`` (default ``$XDG_CACHE_HOME/jointid``,
else ``~/.cache/jointid``), of entries keyed by a digest of everything the answer depends on, the newest
last.  A file that cannot be read or written is ignored: the answer is then computed as before.  Used by the
dataset folders' checks (:mod:`jointid.data.checked`) and the Snakefile's validated configuration
(:func:`jointid.config.snakefile.validated`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

__all__ = ["cache_file", "lookup", "remember"]


def cache_file(name: str) -> Path:
    """The file of the answers called ``name`` (module doc)."""
    base = os.environ.get("JOINTID_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "jointid")
    return Path(base) / f"{name}.json"


def lookup(name: str, key: str):
    """The answer kept under ``key``, or None."""
    return _read(name).get(key)


def remember(name: str, key: str, value, max_entries: int) -> None:
    """Keep ``value`` (JSON) under ``key``, with at most ``max_entries`` answers (the newest)."""
    kept = _read(name)
    kept.pop(key, None)
    kept[key] = value
    _write(name, dict(list(kept.items())[-max_entries:]))


def _read(name: str) -> dict:
    try:
        data = json.loads(cache_file(name).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _write(name: str, data: dict) -> None:
    """Write the answers through the project's atomic write (whole, or not at all: a concurrent start reads the
    old or the new file); a failure is ignored (module doc).  Imported here: a start that finds its answer
    does not load it."""
    from jointid.errors import JointidError
    from jointid.io import write_text

    try:
        write_text(cache_file(name), json.dumps(data))
    except (OSError, JointidError):
        pass
