"""A dataset folder's checks, remembered by its content.

Every Snakemake start validates the configuration, and with it every dataset folder the run reads
(:func:`jointid.config.datasets.check_dataset_folders`): the states in each ``modes.csv`` and the whole
folder's validation (:func:`jointid.data.dataset.validate_dataset`).  That took about 0.75 s of each start,
most of it importing pandas, on folders that rarely change.  The answers are a function of the folder's
files and of this package's code alone, so they are kept in a small file keyed by both
(:func:`folder_key`: the bytes of the dataset's files, :data:`jointid.data.files.DATASET_FILES`, and
:func:`jointid.version.code_digest`):
a folder whose files or checking code changed is read and validated again.

The file is ``$JOINTID_CACHE_DIR/dataset-checks.json`` (:mod:`jointid.usercache`).  It is only a shortcut: a
cache that cannot be read or written is ignored, and the checks then run as before.
"""

from __future__ import annotations

import hashlib
from contextlib import contextmanager
from pathlib import Path

from jointid import usercache

__all__ = ["folder_checks", "folder_key"]

CACHE = "dataset-checks"
"""The answers' file (:func:`jointid.usercache.cache_file`)."""

MAX_ENTRIES = 64
"""Most folders remembered (the newest)."""

_asked: set | None = None  # the folders asked while :func:`recording` (a validation being remembered)


@contextmanager
def recording():
    """The set of the folders :func:`folder_checks` is asked about inside the ``with`` block (a validation
    remembered by :mod:`jointid.config.remembered` depends on them)."""
    global _asked
    outer, _asked = _asked, set()
    try:
        yield _asked
    finally:
        _asked = outer


def folder_key(folder) -> str:
    """Digest of the checking code and of the dataset files in ``folder`` (each file's name, and its bytes or
    that it is absent; other files, e.g. raw time histories, are not read)."""
    from jointid.data.files import DATASET_FILES
    from jointid.version import code_digest

    h = hashlib.sha256(code_digest().encode())
    for name in DATASET_FILES:
        path = Path(folder) / name
        h.update(name.encode() + b"\0")
        h.update(hashlib.sha256(path.read_bytes()).digest() if path.is_file() else b"absent")
    return h.hexdigest()


def folder_checks(folder) -> tuple[dict[str, int] | None, list[str]]:
    """``(modes per state, problems)`` of the dataset folder ``folder``
    (:func:`jointid.data.dataset.modes_per_state`, :func:`jointid.data.dataset.validate_dataset`), from the
    cache when the folder and the code are unchanged since they were last computed."""
    if _asked is not None:
        _asked.add(str(folder))
    try:
        key = folder_key(folder)
    except OSError:  # unreadable: the checks say what is wrong
        key = None
    hit = usercache.lookup(CACHE, key) if key else None
    if isinstance(hit, dict) and isinstance(hit.get("problems"), list):
        states = hit.get("states")
        return (None if states is None else {str(k): int(v) for k, v in states}), [str(p) for p in hit["problems"]]
    from jointid.data.dataset import modes_per_state, validate_dataset  # pandas: only when the folder is new

    states, problems = modes_per_state(folder), validate_dataset(folder)
    if key:
        usercache.remember(CACHE, key, {"states": None if states is None else list(states.items()),
                                        "problems": list(problems)}, MAX_ENTRIES)
    return states, problems
