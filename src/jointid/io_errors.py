"""One-line messages for a result file that cannot be written or read, and the fault hook of the tests.

A full disk, a quota, a read-only file system or a folder without write permission stops a writer
of :mod:`jointid.io`.  :func:`write_error` turns the ``OSError`` into a :class:`ResultWriteError`:
one line naming the file, the space it needs where known and the fix.  :func:`read_error` does the
same for a result file that cannot be read (truncated, damaged).

Fault injection (tests only): the environment variable ``JOINTID_INJECT_FAULT`` holds
``<ERRNO>:<glob>[,<ERRNO>:<glob> ...]``, e.g. ``ENOSPC:*/table2_power_off.csv``.  A write through
:func:`jointid.io.atomic_path` whose target matches the glob (``fnmatch`` on the path as given)
writes its temporary file and then fails with that ``OSError``, as the real fault would.  No
machine needs a small file system or another user for the tests (they run as root in CI, where
permissions do not bite).
"""

from __future__ import annotations

import errno
import fnmatch
import os
import shutil
from pathlib import Path

from jointid.errors import JointidError

FAULT_ENV = "JOINTID_INJECT_FAULT"
REBUILD = "run `make reproduce` again (it removes damaged results and rebuilds them)"

_SPACE = {errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded"}
_ACCESS = {errno.EACCES: "permission denied", errno.EPERM: "operation not permitted",
           errno.EROFS: "read-only file system"}


class ResultWriteError(JointidError):
    """A result file could not be written (disk full, quota, permission, read-only file system)."""


class ResultReadError(JointidError):
    """A result file could not be read or does not match its provenance record."""


def _mb(n_bytes: float) -> str:
    if n_bytes >= 1e5:
        return f"{n_bytes / 1e6:.1f} MB"
    return f"{n_bytes / 1e3:.1f} kB" if n_bytes >= 1e3 else f"{int(n_bytes)} bytes"


def _free_bytes(folder: Path) -> int | None:
    for p in (folder, *folder.parents):
        if p.exists():
            try:
                return shutil.disk_usage(p).free
            except OSError:
                return None
    return None


def write_error(path: str | os.PathLike, exc: OSError, size_bytes: int | None = None) -> JointidError | None:
    """The one-line error for ``exc`` raised while writing ``path``; None for an ``OSError`` of
    another kind (it is not the user's disk or permissions: the caller re-raises it).

    Parameters
    ----------
    path : path-like
        The result file being written.
    exc : OSError
        What the writer raised.
    size_bytes : int, optional
        The size of the file to write, where the writer knows it.
    """
    path = Path(path)
    folder = path.parent
    if exc.errno in _SPACE:
        free = _free_bytes(folder)
        need = f"it needs about {_mb(size_bytes)}" if size_bytes else "its size is not known in advance"
        have = f", {_mb(free)} free there" if free is not None else ""
        return ResultWriteError(
            f"cannot write {path}: {_SPACE[exc.errno]} ({need}{have}); free space on that disk "
            f"(or move results/ to a larger one), then run `make reproduce` again")
    if exc.errno in _ACCESS:
        fix = ("remount it writable or run the workflow in a writable copy" if exc.errno == errno.EROFS
               else f"make the folder and the file writable (chmod u+w {folder} {path})")
        return ResultWriteError(f"cannot write {path}: {_ACCESS[exc.errno]} (the temporary file is made in "
                                f"{folder}); {fix}, then run `make reproduce` again")
    return None


def read_error(path: str | os.PathLike, what: str, checked: bool = False) -> ResultReadError:
    """The one-line error for a result file that cannot be used: ``what`` says why.  ``checked``: the
    file failed its provenance sidecar's check, which ``jointid results heal`` (``make reproduce``)
    repeats and acts on; a file without a sidecar must be deleted by hand."""
    fix = f"{REBUILD}, or delete the file and rerun snakemake" if checked else \
        "delete it and run `make reproduce` again (it rebuilds the file and what depends on it)"
    return ResultReadError(f"cannot read {path}: {what}; {fix}")


def injected_fault(path: str | os.PathLike) -> OSError | None:
    """The ``OSError`` the fault hook (``JOINTID_INJECT_FAULT``) asks for at a write of ``path``, or None."""
    spec = os.environ.get(FAULT_ENV)
    if not spec:
        return None
    for item in spec.split(","):
        name, _, pattern = item.strip().partition(":")
        code = getattr(errno, name, None)
        if code is not None and fnmatch.fnmatch(str(path), pattern):
            return OSError(code, os.strerror(code), str(path))
    return None
