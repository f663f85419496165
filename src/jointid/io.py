"""Atomic file output: a result file is either complete or absent, never half-written.

Every writer goes to a temporary file in the destination folder and renames it into place
(``os.replace`` is atomic on POSIX), so an interrupted run never leaves a corrupt output and never
touches the previous result until the new one is complete.

Temporary files are named ``.<name>.p<pid>h<host>_<random>.tmp`` (``<host>``: 8 hex digits of a
hash of the host name).  A writer killed with SIGKILL cannot remove its own; the next write of the
same target removes it (:func:`remove_stale_temporaries`), and the SIGTERM handler of
:func:`jointid.workflow.run_script` removes those in flight (:func:`remove_in_flight`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import socket
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

STALE_AFTER_S = 3600.0
"""Temporary files of another host (or of an older naming) count as stale after this age."""

_IN_FLIGHT: set[str] = set()
_RANDOM = r"[a-z0-9_]+"
_OURS = re.compile(rf"^p(?P<pid>\d+)h(?P<host>[0-9a-f]{{8}})_{_RANDOM}$")
_LEGACY = re.compile(r"^[a-z0-9_]{8}$")  # ``.<name>.<random>.tmp`` of earlier versions


def _host_tag() -> str:
    return hashlib.sha1(socket.gethostname().encode()).hexdigest()[:8]


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove temporary files that killed writers of ``path`` left beside it.

    A temporary file ``.<name>.p<pid>h<host>_<random>.tmp`` is stale when it was made on this host
    by a process that no longer exists; one of another host (or of the older
    ``.<name>.<random>.tmp`` naming) when it is older than :data:`STALE_AFTER_S`.  Temporaries of
    other targets (e.g. ``<name>.provenance.json``) are never touched.

    Returns
    -------
    list of pathlib.Path
        The files removed.
    """
    path = Path(path)
    prefix, host, now = f".{path.name}.", _host_tag(), time.time()
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        name = p.name
        if not (name.startswith(prefix) and name.endswith(".tmp")) or str(p) in _IN_FLIGHT:
            continue
        middle = name[len(prefix):-len(".tmp")]
        m = _OURS.match(middle)
        try:
            if m and m["host"] == host:
                stale = not _pid_alive(int(m["pid"]))
            elif m or _LEGACY.match(middle):
                stale = now - p.stat().st_mtime > STALE_AFTER_S
            else:
                continue  # another target's temporary file
            if stale and p.is_file():
                p.unlink()
                removed.append(p)
        except FileNotFoundError:  # removed meanwhile by someone else
            continue
    return removed


def remove_in_flight() -> list[str]:
    """Remove the temporary files of writes still in progress in this process (signal handlers)."""
    removed = []
    for tmp in list(_IN_FLIGHT):
        try:
            os.remove(tmp)
            removed.append(tmp)
        except FileNotFoundError:
            pass
        _IN_FLIGHT.discard(tmp)
    return removed


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; on success move it to ``path``, else delete it.

    Stale temporary files of killed earlier writers of ``path`` are removed first.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.p{os.getpid()}h{_host_tag()}_",
                               suffix=".tmp")
    os.close(fd)
    _IN_FLIGHT.add(tmp)
    try:
        yield Path(tmp)
        # mkstemp creates the file private (0600); results get the permissions of any new file
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    finally:
        _IN_FLIGHT.discard(tmp)
        if os.path.exists(tmp):
            os.remove(tmp)


def write_text(path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_csv(df, path, float_format: str = "%.10g") -> None:
    """CSV with a fixed float format so identical results give byte-identical files."""
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False, float_format=float_format, lineterminator="\n")


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float):
        return float(f"{obj:.12g}")
    return obj


def write_json(path, obj) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(_jsonable(obj), indent=2, sort_keys=True) + "\n")


def read_json(path):
    return json.loads(Path(path).read_text())


def write_npz(path, **arrays) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
