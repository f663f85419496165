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
provenance(stamp, *, inputs=None, repo=None) -> dict  (stamp: jointid.config.ConfigStamp.of(config))
write_provenance(table_path, stamp, *, inputs=None, repo=None) -> pathlib.Path
provenance_path(table_path) -> pathlib.Path
git_state(repo=None, sections=None) -> (commit, dirty, where)
pin_config_state(paths) -> None  (the Snakefile: which config sections differ from the commit, at load)
check_sidecar(path) -> str | None  (why ``path`` does not match its sidecar, or None)
run_record(stamp, workdir=".") -> dict  (the provenance of a whole run, as the report page shows it)

``git_dirty`` describes the tree when the output is written, with one exception: the config files
the run loaded count as they were at load time (:func:`pin_config_state`), and only in the sections
the output depends on.  An edit of ``config.yaml`` during a run does not change that run's values,
so it does not make its outputs dirty; an edit before the run does, and after it is reverted the
rules it touched run again and write clean records.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
from collections.abc import Iterable, Mapping
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from jointid import io
from jointid.config import ConfigStamp

__all__ = ["PACKAGES", "REPORT_PACKAGES", "SUFFIX", "check_sidecar", "git_state", "pin_config_state", "provenance",
           "provenance_path", "run_record", "sha256_file", "write_provenance"]

PACKAGES = ("jointid", "numpy", "scipy", "scikit-fem", "pandas", "snakemake")
"""Distributions whose versions are recorded."""

REPORT_PACKAGES = ("jointid", "numpy", "scipy", "pandas", "scikit-fem", "snakemake", "matplotlib", "pyyaml",
                   "jsonschema", "meshio", "pypardiso")
"""Distributions whose versions the report page lists."""

SUFFIX = ".provenance.json"
UNKNOWN = "unknown"
CONFIG_ENV = "JOINTID_CONFIG_AT_LOAD"
"""Environment variable holding the config files of the run and the sections that differed from the
commit when the Snakefile loaded them (:func:`pin_config_state`); jobs inherit it."""
_GIT_TIMEOUT_S = 10.0


def _git(args: list[str], cwd: Path, strip: bool = True) -> str | None:
    """Output of ``git <args>`` run in ``cwd`` (stripped unless ``strip`` is False), or None if git fails
    or is missing."""
    try:
        out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                             timeout=_GIT_TIMEOUT_S, check=False,
                             env={**os.environ, "GIT_OPTIONAL_LOCKS": "0", "LC_ALL": "C"})
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() if strip else out.stdout


def _dirty_paths(folder: Path) -> set[Path] | None:
    """Absolute paths of the tracked files that differ from HEAD (None if git cannot tell)."""
    top = _git(["rev-parse", "--show-toplevel"], folder)
    out = None if top is None else _git(["status", "--porcelain", "-z", "--untracked-files=no"], folder, strip=False)
    if out is None:
        return None
    paths = set()
    for entry in out.split("\0"):
        if len(entry) > 3 and entry[2] == " ":  # "XY path" (a rename's old path follows as its own entry)
            paths.add((Path(top) / entry[3:]).resolve())
    return paths


def _pinned() -> dict | None:
    try:
        rec = json.loads(os.environ.get(CONFIG_ENV, ""))
    except ValueError:
        return None
    return rec if isinstance(rec, dict) else None


def _commit_in(folder: Path, sections: Iterable[str] | None = None) -> tuple[str, bool | None] | None:
    if not folder.is_dir():
        return None
    commit = _git(["rev-parse", "--verify", "HEAD"], folder)
    if not commit:
        return None
    dirty = _dirty_paths(folder)
    if dirty is None:
        return commit, None
    pinned = _pinned()
    if pinned is None:
        return commit, bool(dirty)
    config_files = {Path(p).resolve() for p in pinned.get("files", [])}
    changed = set(pinned.get("changed_sections", []))
    if sections is not None:
        changed &= set(sections)
    return commit, bool(dirty - config_files) or bool(changed)


def _yaml_sections(text: str | None) -> dict:
    import yaml

    try:
        doc = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return {"<unreadable>": text}
    return doc if isinstance(doc, dict) else {"<document>": doc}


def config_changes(paths: Iterable[str | os.PathLike]) -> dict:
    """The config files ``paths`` and the top-level sections in which they differ from HEAD now.

    Returns
    -------
    dict
        ``files`` (absolute paths) and ``changed_sections`` (sorted): every top-level key whose value
        in a file differs from the committed file's (all of a file's keys when git cannot tell).
    """
    files, changed = [], set()
    for p in map(Path, paths):
        files.append(str(p.resolve()))
        dirty = _dirty_paths(p.resolve().parent)
        if dirty is None or p.resolve() not in dirty:
            continue  # outside a checkout, tracked and unchanged, or untracked: no part of the commit's changes
        top = _git(["rev-parse", "--show-toplevel"], p.resolve().parent)
        rel = p.resolve().relative_to(top).as_posix() if top else None
        old = _yaml_sections(_git(["show", f"HEAD:{rel}"], p.resolve().parent) if rel else None)
        new = _yaml_sections(p.read_text() if p.is_file() else None)
        changed |= {k for k in set(old) | set(new) if old.get(k) != new.get(k)}
    return {"files": files, "changed_sections": sorted(map(str, changed))}


def pin_config_state(paths: Iterable[str | os.PathLike]) -> None:
    """Record (in :data:`CONFIG_ENV`, inherited by the jobs) the config files of the run and the
    sections they change against the commit, as loaded.  A second call (Snakemake parses the
    Snakefile again inside each job) keeps the first record."""
    if CONFIG_ENV not in os.environ:
        os.environ[CONFIG_ENV] = json.dumps(config_changes(paths))


def git_state(repo: str | os.PathLike | None = None,
              sections: Iterable[str] | None = None) -> tuple[str, bool | None, str | None]:
    """Git commit of the code that runs.

    Parameters
    ----------
    repo : path-like, optional
        Folder to ask.  Default: the working directory (where the Snakefile is run); if that is not
        a git checkout, the folder of the installed ``jointid`` source (editable install).
    sections : iterable of str, optional
        The config sections the output depends on: a config file pinned at load
        (:func:`pin_config_state`) makes it dirty only through these (default: through any).

    Returns
    -------
    (commit, dirty, where)
        ``commit``: 40 hex digits, or ``"unknown"`` outside a git checkout (or without git);
        ``dirty``: True if tracked files differ from the commit (the run's config files as loaded,
        in ``sections``), None if unknown;
        ``where``: ``"given"``, ``"workdir"``, ``"package"`` or None.
    """
    if repo is not None:
        candidates = [("given", Path(repo))]
    else:
        candidates = [("workdir", Path.cwd()), ("package", Path(__file__).resolve().parent)]
    for where, folder in candidates:
        found = _commit_in(folder, sections)
        if found is not None:
            return found[0], found[1], where
    return UNKNOWN, None, None


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        if dist == "jointid":
            from jointid.version import __version__

            return __version__
        return "not installed"


def sha256_file(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def provenance(stamp: ConfigStamp, *, inputs: Iterable[str | os.PathLike] | None = None,
               repo: str | os.PathLike | None = None, input_hashes: Mapping[str, str] | None = None) -> dict:
    """Provenance record of a result computed from the configuration ``stamp`` names.

    Parameters
    ----------
    stamp : ConfigStamp
        The configuration (or the sections of it) the result depends on:
        :meth:`jointid.config.ConfigStamp.of` of it.
    inputs : iterable of path-like, optional
        Input files; their SHA-256 is recorded (missing files as ``"missing"``).
    repo : path-like, optional
        Folder whose git commit is recorded (default: see :func:`git_state`).
    input_hashes : mapping, optional
        SHA-256 of inputs already hashed ({path: hex}); not hashed again.

    Returns
    -------
    dict
        ``git_commit`` (str, ``"unknown"`` outside a git checkout), ``git_dirty`` (bool or None),
        ``git_where``, ``config_hash`` (12 hex digits), ``config_sections`` (sorted top-level keys),
        ``packages`` ({distribution: version}), ``python`` (version), ``platform``,
        ``timestamp_utc`` (ISO 8601, seconds, ``Z``) and, if given, ``inputs`` ({path: sha256}).
    """
    commit, dirty, where = git_state(repo, sections=list(stamp.sections))
    rec = {
        "git_commit": commit,
        "git_dirty": dirty,
        "git_where": where,
        "config_hash": stamp.hash,
        "config_sections": sorted(stamp.sections),
        "packages": {d: _version(d) for d in PACKAGES},
        "python": platform.python_version(),
        "platform": platform.platform(terse=True),
        "timestamp_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }
    if inputs is not None:
        known = input_hashes or {}
        rec["inputs"] = {str(p): known.get(str(p)) or (sha256_file(p) if Path(p).is_file() else "missing")
                         for p in inputs}
    return rec


def provenance_path(table_path: str | os.PathLike) -> Path:
    """``<table>.provenance.json`` beside ``table_path``."""
    p = Path(table_path)
    return p.with_name(p.name + SUFFIX)


def write_provenance(table_path: str | os.PathLike, stamp: ConfigStamp, *,
                     inputs: Iterable[str | os.PathLike] | None = None,
                     repo: str | os.PathLike | None = None, record: Mapping | None = None) -> Path:
    """Write the provenance of ``table_path`` atomically to ``<table>.provenance.json``.

    Call it right after the table is written: the record includes the table's SHA-256, so a
    sidecar can be checked against the table it describes (:func:`check_sidecar`).  ``record``: a
    :func:`provenance` record already made for the job (its outputs share it).

    Returns
    -------
    pathlib.Path
        Path of the sidecar.
    """
    table_path = Path(table_path)
    rec = dict(record) if record is not None else provenance(stamp, inputs=inputs, repo=repo)
    rec["table"] = table_path.name
    rec["table_sha256"] = sha256_file(table_path) if table_path.is_file() else "missing"
    out = provenance_path(table_path)
    io.write_json(out, rec)
    return out


def check_sidecar(path: str | os.PathLike, sha256: str | None = None) -> str | None:
    """Why the result ``path`` does not match its sidecar ``<path>.provenance.json``, or None when it
    does, or when it has no sidecar (a file no rule records, or one of an earlier version).

    ``sha256``: the file's hash if already computed.  A sidecar that cannot be read counts as a
    mismatch: the result can no longer be checked.
    """
    side = provenance_path(path)
    if not side.is_file():
        return None
    try:
        recorded = json.loads(side.read_text()).get("table_sha256")
    except (ValueError, UnicodeDecodeError, AttributeError, OSError):
        return f"its provenance record {side.name} is damaged (not valid JSON)"
    if not Path(path).is_file():
        return None
    actual = sha256 or sha256_file(path)
    if recorded != actual:
        return (f"its SHA-256 {actual[:12]}... differs from the one {side.name} recorded when it was written "
                f"({str(recorded)[:12]}...): the file changed or was cut short since")
    return None


def _commit_text(folder: Path) -> str:
    """Git commit of ``folder`` as the report shows it: the SHA, ``(with uncommitted changes)`` when
    tracked files differ, or ``not a git checkout``."""
    found = _commit_in(folder)
    if found is None:
        return "not a git checkout"
    commit, dirty = found
    return commit + (" (with uncommitted changes)" if dirty else "")


def run_record(stamp: ConfigStamp, workdir: str | os.PathLike = ".") -> dict:
    """Provenance of a whole run (``stamp``: of its configuration), as the report page shows it.

    Returns
    -------
    dict
        ``workflow_commit`` (of ``workdir``), ``package_commit`` (of the jointid package's folder),
        ``config_hash`` (:func:`jointid.config.config_hash` of the configuration), ``python``,
        ``platform`` and ``versions`` ({distribution: version} of :data:`REPORT_PACKAGES`).
    """
    return {"workflow_commit": _commit_text(Path(workdir)),
            "package_commit": _commit_text(Path(__file__).resolve().parents[1]),
            "config_hash": stamp.hash,
            "python": platform.python_version(), "platform": platform.platform(),
            "versions": {d: _version(d) for d in REPORT_PACKAGES}}
