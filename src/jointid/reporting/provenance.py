"""Provenance records that travel with every result table.

A table ``results/tables/table2_power_off.csv`` gets a sidecar
``results/tables/table2_power_off.csv.provenance.json`` holding what produced it::

    {"git_commit": "2a5170e...", "git_dirty": false, "git_where": "workdir",
     "config_hash": "3f9c0a1b2c4d", "config_sections": ["joints", "rig", ...],
     "packages": {"jointid": "0.1.0", "numpy": "2.4.0", ...}, "python": "3.11.9",
     "timestamp_utc": "2026-11-22T02:56:35Z", "table": "table2_power_off.csv",
     "table_sha256": "...", "inputs": {"results/identify/power_off/verify.csv": "<sha256>"}}

The sidecar is the only place where wall-clock time appears: the tables themselves stay
byte-identical between runs of the same configuration.  The config hash is
:func:`jointid.config.config_hash` of the configuration *given* (normally the sections the stage
depends on, i.e. ``snakemake.params.cfg``), so it changes exactly when the stage's inputs change.

Public API
----------
provenance(config, *, inputs=None, repo=None) -> dict
write_provenance(table_path, config, *, inputs=None, repo=None) -> pathlib.Path
provenance_path(table_path) -> pathlib.Path
git_state(repo=None) -> (commit, dirty, where)
run_record(config, workdir=".") -> dict  (the provenance of a whole run, as the report page shows it)
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from collections.abc import Iterable, Mapping
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from jointid import io
from jointid.config import config_hash

__all__ = ["PACKAGES", "REPORT_PACKAGES", "SUFFIX", "git_state", "provenance", "provenance_path", "run_record",
           "sha256_file", "write_provenance"]

PACKAGES = ("jointid", "numpy", "scipy", "scikit-fem", "pandas", "snakemake")
"""Distributions whose versions are recorded."""

REPORT_PACKAGES = ("jointid", "numpy", "scipy", "pandas", "scikit-fem", "snakemake", "matplotlib", "pyyaml",
                   "jsonschema", "meshio", "pypardiso")
"""Distributions whose versions the report page lists."""

SUFFIX = ".provenance.json"
UNKNOWN = "unknown"
_GIT_TIMEOUT_S = 10.0


def _git(args: list[str], cwd: Path) -> str | None:
    """Output of ``git <args>`` run in ``cwd`` (stripped), or None if git fails or is missing."""
    try:
        out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                             timeout=_GIT_TIMEOUT_S, check=False,
                             env={**os.environ, "GIT_OPTIONAL_LOCKS": "0", "LC_ALL": "C"})
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def _commit_in(folder: Path) -> tuple[str, bool | None] | None:
    if not folder.is_dir():
        return None
    commit = _git(["rev-parse", "--verify", "HEAD"], folder)
    if not commit:
        return None
    status = _git(["status", "--porcelain", "--untracked-files=no"], folder)
    return commit, (None if status is None else bool(status))


def git_state(repo: str | os.PathLike | None = None) -> tuple[str, bool | None, str | None]:
    """Git commit of the code that runs.

    Parameters
    ----------
    repo : path-like, optional
        Folder to ask.  Default: the working directory (where the Snakefile is run); if that is not
        a git checkout, the folder of the installed ``jointid`` source (editable install).

    Returns
    -------
    (commit, dirty, where)
        ``commit``: 40 hex digits, or ``"unknown"`` outside a git checkout (or without git);
        ``dirty``: True if tracked files differ from the commit, None if unknown;
        ``where``: ``"given"``, ``"workdir"``, ``"package"`` or None.
    """
    if repo is not None:
        candidates = [("given", Path(repo))]
    else:
        candidates = [("workdir", Path.cwd()), ("package", Path(__file__).resolve().parent)]
    for where, folder in candidates:
        found = _commit_in(folder)
        if found is not None:
            return found[0], found[1], where
    return UNKNOWN, None, None


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        if dist == "jointid":
            from jointid import __version__

            return __version__
        return "not installed"


def sha256_file(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def provenance(config: Mapping, *, inputs: Iterable[str | os.PathLike] | None = None,
               repo: str | os.PathLike | None = None) -> dict:
    """Provenance record of a result computed from ``config``.

    Parameters
    ----------
    config : mapping
        The configuration (or the sections of it) the result depends on.
    inputs : iterable of path-like, optional
        Input files; their SHA-256 is recorded (missing files as ``"missing"``).
    repo : path-like, optional
        Folder whose git commit is recorded (default: see :func:`git_state`).

    Returns
    -------
    dict
        ``git_commit`` (str, ``"unknown"`` outside a git checkout), ``git_dirty`` (bool or None),
        ``git_where``, ``config_hash`` (12 hex digits), ``config_sections`` (sorted top-level keys),
        ``packages`` ({distribution: version}), ``python`` (version), ``platform``,
        ``timestamp_utc`` (ISO 8601, seconds, ``Z``) and, if given, ``inputs`` ({path: sha256}).
    """
    commit, dirty, where = git_state(repo)
    rec = {
        "git_commit": commit,
        "git_dirty": dirty,
        "git_where": where,
        "config_hash": config_hash(config),
        "config_sections": sorted(str(k) for k in config),
        "packages": {d: _version(d) for d in PACKAGES},
        "python": platform.python_version(),
        "platform": platform.platform(terse=True),
        "timestamp_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }
    if inputs is not None:
        rec["inputs"] = {str(p): (sha256_file(p) if Path(p).is_file() else "missing") for p in inputs}
    return rec


def provenance_path(table_path: str | os.PathLike) -> Path:
    """``<table>.provenance.json`` beside ``table_path``."""
    p = Path(table_path)
    return p.with_name(p.name + SUFFIX)


def write_provenance(table_path: str | os.PathLike, config: Mapping, *,
                     inputs: Iterable[str | os.PathLike] | None = None,
                     repo: str | os.PathLike | None = None) -> Path:
    """Write the provenance of ``table_path`` atomically to ``<table>.provenance.json``.

    Call it right after the table is written: the record includes the table's SHA-256, so a
    sidecar can be checked against the table it describes.

    Returns
    -------
    pathlib.Path
        Path of the sidecar.
    """
    table_path = Path(table_path)
    rec = provenance(config, inputs=inputs, repo=repo)
    rec["table"] = table_path.name
    rec["table_sha256"] = sha256_file(table_path) if table_path.is_file() else "missing"
    out = provenance_path(table_path)
    io.write_json(out, rec)
    return out


def _commit_text(folder: Path) -> str:
    """Git commit of ``folder`` as the report shows it: the SHA, ``(with uncommitted changes)`` when
    tracked files differ, or ``not a git checkout``."""
    found = _commit_in(folder)
    if found is None:
        return "not a git checkout"
    commit, dirty = found
    return commit + (" (with uncommitted changes)" if dirty else "")


def run_record(config: Mapping, workdir: str | os.PathLike = ".") -> dict:
    """Provenance of a whole run, as the report page shows it.

    Returns
    -------
    dict
        ``workflow_commit`` (of ``workdir``), ``package_commit`` (of the jointid package's folder),
        ``config_hash`` (:func:`jointid.config.config_hash` of ``config``), ``python``,
        ``platform`` and ``versions`` ({distribution: version} of :data:`REPORT_PACKAGES`).
    """
    return {"workflow_commit": _commit_text(Path(workdir)),
            "package_commit": _commit_text(Path(__file__).resolve().parents[1]),
            "config_hash": config_hash(config),
            "python": platform.python_version(), "platform": platform.platform(),
            "versions": {d: _version(d) for d in REPORT_PACKAGES}}
