"""Atomic file output: a result file is either complete or absent, never half-written.

Every writer goes to a temporary file in the destination folder and renames it into place
(``os.replace`` is atomic on POSIX), so an interrupted run never leaves a corrupt output and never
touches the previous result until the new one is complete.

Temporary files are named ``.<name>.p<pid>h<host>_<random>.tmp`` (``<host>``: 8 hex digits of a
hash of the host name).  A writer killed with SIGKILL cannot remove its own; the next write of the
same target removes it (:func:`remove_stale_temporaries`), so does ``jointid results heal`` before
``make reproduce`` runs (:func:`remove_stale_below`), and the SIGTERM handler of
:func:`jointid.stages.runner.run_script` removes those in flight (:func:`remove_in_flight`).

A full disk, a quota, a read-only file system or a missing permission ends a write with one line
(:class:`jointid.io_errors.ResultWriteError`: the file, the space it needs where known, the fix)
and leaves no temporary file.  A result that cannot be read is named the same way
(:func:`read_json`, :func:`read_csv`, :func:`load_npz`).
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

from jointid.io_errors import injected_fault, read_error, write_error

STALE_AFTER_S = 3600.0
"""Temporary files of another host (or of an older naming) count as stale after this age."""

_IN_FLIGHT: set[str] = set()
_RANDOM = r"[a-z0-9_]+"
_OURS = re.compile(rf"^p(?P<pid>\d+)h(?P<host>[0-9a-f]{{8}})_{_RANDOM}$")
_LEGACY = re.compile(r"^[a-z0-9_]{8}$")  # ``.<name>.<random>.tmp`` of earlier versions


def _host_tag() -> str:
    return hashlib.sha1(socket.gethostname().encode()).hexdigest()[:8]


def _pid_alive(pid: int) -> bool:
    """Whether process ``pid`` runs; a zombie (killed, not yet reaped by its parent or by an init that
    reaps late, as in many containers) has ended and writes nothing more."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        pass
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True  # no /proc: the signal's answer stands
    return stat[stat.rfind(")") + 2:].split()[0] != "Z"


def _is_stale(p: Path, middle: str, host: str, now: float) -> bool | None:
    """Whether the temporary file ``p`` (``middle``: its name between target and ``.tmp``) is stale;
    None when the name is not one of :func:`atomic_path`'s."""
    m = _OURS.match(middle)
    if m and m["host"] == host:
        return not _pid_alive(int(m["pid"]))
    if m or _LEGACY.match(middle):
        return now - p.stat().st_mtime > STALE_AFTER_S
    return None


def _remove_if_stale(p: Path, middle: str, host: str, now: float) -> bool:
    try:
        if str(p) not in _IN_FLIGHT and _is_stale(p, middle, host, now) and p.is_file():
            p.unlink()
            return True
    except FileNotFoundError:  # removed meanwhile by someone else
        pass
    return False


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
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return []
    return [p for p in siblings if p.name.startswith(prefix) and p.name.endswith(".tmp")
            and _remove_if_stale(p, p.name[len(prefix):-len(".tmp")], host, now)]


_ANY_TEMPORARY = re.compile(r"^\..+?\.(?P<middle>p\d+h[0-9a-f]{8}_[a-z0-9_]+)\.tmp$")


def remove_stale_below(folder: str | os.PathLike) -> list[Path]:
    """Remove the stale temporary files (:func:`remove_stale_temporaries`) of every target below
    ``folder``, e.g. the 150 MB ``.matrices.npz.*.tmp`` of a mesh job killed with SIGKILL.

    Returns
    -------
    list of pathlib.Path
        The files removed.
    """
    host, now, removed = _host_tag(), time.time(), []
    for root, _dirs, files in os.walk(folder):
        for name in files:
            m = _ANY_TEMPORARY.match(name)
            if m and _remove_if_stale(Path(root, name), m["middle"], host, now):
                removed.append(Path(root, name))
    return sorted(removed)


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
def atomic_path(path: str | os.PathLike, size_bytes: int | None = None):
    """Yield a temporary path beside ``path``; on success move it to ``path``, else delete it.

    Stale temporary files of killed earlier writers of ``path`` are removed first.  A full disk,
    a quota, a read-only file system or a missing permission raise
    :class:`jointid.io_errors.ResultWriteError` (one line; ``size_bytes``, where the writer knows
    it, is the space the file needs), and no temporary file stays.
    """
    path = Path(path)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.p{os.getpid()}h{_host_tag()}_",
                                   suffix=".tmp")
        os.close(fd)
        _IN_FLIGHT.add(tmp)
        yield Path(tmp)
        fault = injected_fault(path)  # the tests' fault hook (jointid.io_errors): after the data, as a full disk
        if fault is not None:
            raise fault
        # mkstemp creates the file private (0600); results get the permissions of any new file
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except OSError as exc:
        err = write_error(path, exc, size_bytes)
        if err is None:
            raise
        raise err from None
    finally:
        if tmp is not None:
            _IN_FLIGHT.discard(tmp)
            if os.path.exists(tmp):
                os.remove(tmp)


def write_text(path, text: str) -> None:
    with atomic_path(path, len(text.encode())) as tmp:
        tmp.write_text(text)


def csv_text(df, float_format: str = "%.10g") -> str:
    """The text :func:`write_csv` writes of ``df``."""
    return df.to_csv(index=False, float_format=float_format, lineterminator="\n")


def write_csv(df, path, float_format: str = "%.10g") -> None:
    """CSV with a fixed float format so identical results give byte-identical files (rendered first,
    so that a full disk can say how much space the file needs)."""
    data = csv_text(df, float_format).encode("utf-8")
    with atomic_path(path, len(data)) as tmp:
        tmp.write_bytes(data)


def through_csv(df):
    """``df`` as :func:`read_csv` reads back the file :func:`write_csv` writes of it (floats at 10
    significant digits): what the workflow's next stage gets, for a caller that keeps the table in memory."""
    import io as _io

    return read_csv(_io.StringIO(csv_text(df)))


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


def json_text(obj) -> str:
    """The text :func:`write_json` writes of ``obj`` (floats at 12 significant digits, keys sorted)."""
    return json.dumps(_jsonable(obj), indent=2, sort_keys=True) + "\n"


def write_json(path, obj) -> None:
    text = json_text(obj)
    with atomic_path(path, len(text.encode())) as tmp:
        tmp.write_text(text)


def through_json(obj):
    """``obj`` as :func:`read_json` reads back the file :func:`write_json` writes of it: what the workflow's
    next stage gets, for a caller that keeps the document in memory."""
    return json.loads(json_text(obj))


def read_json(path):
    """The JSON document in ``path``; a file that is not valid JSON (e.g. cut short) raises
    :class:`jointid.io_errors.ResultReadError` naming it."""
    try:
        return json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:  # json.JSONDecodeError is a ValueError
        raise read_error(path, f"not valid JSON ({exc})") from None


def read_csv(path, **kwargs):
    """``pandas.read_csv(path)``; a file that cannot be parsed raises
    :class:`jointid.io_errors.ResultReadError` naming it."""
    import pandas as pd

    try:
        return pd.read_csv(path, **kwargs)
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise read_error(path, f"not a readable CSV table ({type(exc).__name__}: {exc})") from None


def load_npz(path) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file, read into memory; a damaged file (e.g. cut short: no zip
    directory) raises :class:`jointid.io_errors.ResultReadError` naming it."""
    import zipfile

    try:
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:  # closed even when the archive is damaged
            return {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, EOFError, ValueError, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise read_error(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None


def _nbytes(arrays) -> int:
    return sum(int(np.asarray(a).nbytes) for a in arrays.values())


def write_npz(path, **arrays) -> None:
    with atomic_path(path, _nbytes(arrays)) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)


# ------------------------------------------------------------------ memory-mappable .npz
NPZ_ALIGN = 64  # bytes: the array data of every member starts at a multiple of this in the file
_PAD_ID = 0x6A6A  # id of the zip extra field that pads a local header (ignored by zip readers)


def write_npz_mappable(path, arrays: dict) -> None:
    """Write ``arrays`` as an uncompressed ``.npz`` whose array data are aligned in the file.

    Any ``np.load`` reads it; :func:`map_npz` maps it without a copy.  Each member's local zip header
    carries an extra field sized so that the ``.npy`` data start at a multiple of
    :data:`NPZ_ALIGN` bytes from the start of the file, which a memory map needs to give aligned
    arrays.  Written atomically (:func:`atomic_path`).
    """
    import io as _io
    import zipfile

    with atomic_path(path, _nbytes(arrays)) as tmp, \
            zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, value in arrays.items():
            arr = np.asarray(value)
            if not arr.flags.c_contiguous:
                arr = np.ascontiguousarray(arr)
            if arr.dtype.hasobject:
                raise ValueError(f"write_npz_mappable: '{name}' holds Python objects; only plain arrays map")
            head = _io.BytesIO()
            np.lib.format.write_array_header_1_0(head, np.lib.format.header_data_from_array_1_0(arr))
            if len(head.getvalue()) > 65535 - 10:  # the 1.0 header is limited; 2.0 has room
                head = _io.BytesIO()
                np.lib.format.write_array_header_2_0(head, np.lib.format.header_data_from_array_1_0(arr))
            header = head.getvalue()
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED
            info.file_size = len(header) + arr.nbytes
            zip64 = info.file_size * 1.05 > zipfile.ZIP64_LIMIT  # as zipfile decides it
            fixed = 30 + len(info.filename.encode()) + (20 if zip64 else 0) + 4 + len(header)
            pad = -(zf.fp.tell() + fixed) % NPZ_ALIGN
            info.extra = np.array([_PAD_ID, pad], "<u2").tobytes() + b"\0" * pad
            with zf.open(info, "w", force_zip64=zip64) as out:
                out.write(header)
                if arr.nbytes:
                    out.write(memoryview(arr.reshape(-1)).cast("B"))


def map_npz(path) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file, as read-only views of one memory map of it where possible.

    A member stored uncompressed whose data are aligned (as :func:`write_npz_mappable` writes them)
    is not read: its pages are loaded on first touch and shared by every process that maps the same
    file.  Other members (compressed, unaligned, object arrays) are read as ``np.load`` would.  A
    damaged file raises :class:`jointid.io_errors.ResultReadError` naming it.
    """
    import zipfile

    try:
        return _map_npz(path)
    except (zipfile.BadZipFile, EOFError, ValueError, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise read_error(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None


def _map_npz(path) -> dict[str, np.ndarray]:
    import io as _io
    import mmap
    import zipfile

    out: dict[str, np.ndarray] = {}
    with open(path, "rb") as fh, zipfile.ZipFile(fh) as zf:
        size = os.fstat(fh.fileno()).st_size
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if size else None
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            arr = None
            if mm is not None and info.compress_type == zipfile.ZIP_STORED:
                off = info.header_offset
                n_name, n_extra = np.frombuffer(mm, "<u2", 2, off + 26)
                start = off + 30 + int(n_name) + int(n_extra)
                head = _io.BytesIO(mm[start: start + min(info.file_size, 65536 + 16)])
                version = np.lib.format.read_magic(head)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                shape, fortran, dtype = read(head)
                data = start + head.tell()
                if not dtype.hasobject and data % max(dtype.alignment, 1) == 0:
                    count = int(np.prod(shape, dtype=np.int64))
                    arr = np.frombuffer(mm, dtype, count, data).reshape(shape, order="F" if fortran else "C")
            if arr is None:
                with zf.open(info) as member:
                    arr = np.lib.format.read_array(member, allow_pickle=False)
            out[name] = arr
    return out


def _mapping_of(arr):
    """The :class:`mmap.mmap` an array is a view of (:func:`map_npz`), or None."""
    import mmap

    obj = arr
    for _ in range(8):  # ndarray views -> the memoryview np.frombuffer made -> the map
        obj = obj.obj if isinstance(obj, memoryview) else getattr(obj, "base", None)
        if obj is None or isinstance(obj, mmap.mmap):
            return obj
    return None


def release_mapped(arrays) -> int:
    """Drop the pages of the memory maps behind ``arrays`` (views made by :func:`map_npz`) from this
    process (``MADV_DONTNEED``), once the arrays have been copied into what a computation keeps.

    The file's pages stay in the page cache and come back on the next touch, with the same contents
    (the maps are read-only), but no longer count in this process's resident memory while a
    factorisation runs.  Returns the number of maps released; arrays not backed by a map are
    skipped, and so is every map where the platform has no ``madvise``.
    """
    import mmap

    maps = {id(m): m for m in map(_mapping_of, arrays) if m is not None and not m.closed}
    if not hasattr(mmap, "MADV_DONTNEED"):
        return 0
    for m in maps.values():
        m.madvise(mmap.MADV_DONTNEED)
    return len(maps)

