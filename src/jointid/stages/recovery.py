"""``jointid results heal``: make a folder's results safe to build on after a crash (``make reproduce`` runs it
before Snakemake).

In this order, and only when no Snakemake run holds the folder's lock:

1. **Orphans.** Jobs of a ``snakemake`` that was killed may still run and write into the new run; they
   are stopped (:mod:`jointid.stages.jobs` says why stopping, not waiting or refusing).
2. **Stale temporary files** of killed writers (``.<name>.p<pid>h<host>_<random>.tmp``, e.g. a 150 MB
   ``.matrices.npz.*.tmp``) are removed.
3. **Damaged results.** Every result with a provenance sidecar is checked against the SHA-256 the
   sidecar recorded; a file that differs (cut short, changed since) or whose sidecar is damaged is
   removed with its sidecar.  The default target of the Snakefile names every result, so Snakemake
   then rebuilds it and everything that depends on it.
4. **A fresh start for the diagnoses.** When any of the above was repaired, the diagnoses' kept
   subspaces (``results/diagnosis/*/subspace.npz``, ``diagnosis.reuse_subspace``) are removed: a
   diagnosis the rebuild reruns then starts afresh, as in an uninterrupted run from clean, and its files
   come out byte-identical to that run's (one started from a kept subspace agrees only to the solver's
   tolerance, and a pairing decided at a near tie can go the other way).
5. **Writable folders.** A results folder without write permission stops here, in one line, instead
   of inside Snakemake.

Each thing done prints one line.  Exit status 0 when the folder is ready, 1 when it is not (a line
says why and what to do).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from jointid import io
from jointid.reporting.provenance import SUFFIX, check_sidecar, provenance_path
from jointid.stages import jobs

LOCKS = Path(".snakemake") / "locks"


def locked(workdir: Path) -> bool:
    """Whether a Snakemake run (alive, or killed without cleanup) holds the folder's lock."""
    folder = workdir / LOCKS
    return folder.is_dir() and any(folder.iterdir())


def stop_orphans(workdir: Path) -> list[str]:
    """Stop the jobs of a killed ``snakemake`` still running in ``workdir``; one line each."""
    lines = []
    for rec in jobs.running(workdir):
        how = jobs.stop(rec)
        lines.append(f"job {rec['rule']} (pid {rec['pid']}, started {rec['started_utc']}) of a killed snakemake "
                     f"was still running: {how}; its outputs are rebuilt")
    return lines


def _rel(path, workdir: Path) -> str:
    return os.path.relpath(path, workdir)


def remove_temporaries(results: Path, workdir: Path) -> list[str]:
    """Remove the stale temporary files below ``results``; one line for all of them."""
    removed = [_rel(p, workdir) for p in io.remove_stale_below(results)] if results.is_dir() else []
    return [f"removed {len(removed)} stale temporary file(s) of killed writers: "
            + ", ".join(str(p) for p in removed[:3]) + (" ..." if len(removed) > 3 else "")] if removed else []


def remove_damaged(results: Path, workdir: Path) -> list[str]:
    """Remove each result that does not match its sidecar (and the sidecar); one line each."""
    lines = []
    for side in sorted(results.rglob(f"*{SUFFIX}")) if results.is_dir() else []:
        out = side.with_name(side.name[:-len(SUFFIX)])
        if not out.is_file():
            continue  # missing: Snakemake builds it anyway
        why = check_sidecar(out)
        if why:
            for p in (out, provenance_path(out)):
                p.unlink(missing_ok=True)
            lines.append(f"removed damaged {_rel(out, workdir)}: {why}; it is rebuilt, with what depends on it")
    return lines


def forget_subspaces(results: Path, workdir: Path) -> list[str]:
    """Remove the diagnoses' kept subspaces (step 4); one line for all of them."""
    # the default study's (results/diagnosis/) and those of named studies (results/<run.name>/diagnosis/)
    kept = sorted([*results.glob("diagnosis/*/subspace.npz"), *results.glob("*/diagnosis/*/subspace.npz")])
    for p in kept:
        p.unlink(missing_ok=True)
        for basis in p.parent.glob(f"{p.stem}.basis-*.npy"):  # its basis (jointid.fe.warmstart, apart)
            basis.unlink(missing_ok=True)
    return [f"removed {len(kept)} kept diagnosis subspace(s) ({', '.join(_rel(p, workdir) for p in kept[:2])}"
            f"{' ...' if len(kept) > 2 else ''}): the diagnoses rerun afresh, as from clean"] if kept else []


def unwritable(results: Path, workdir: Path) -> list[str]:
    """One line per results folder the workflow cannot write to (permission, read-only file system)."""
    lines = []
    for root, _dirs, _files in os.walk(results) if results.is_dir() else []:
        if not os.access(root, os.W_OK | os.X_OK):
            rel = _rel(root, workdir)
            lines.append(f"cannot write in {rel}: permission denied or a read-only file system; make it writable "
                         f"(chmod u+w {rel}), then run `make reproduce` again")
    return lines


def snakemake_command(workdir: Path) -> str:
    """How to call the ``snakemake`` installed beside this Python from ``workdir``: ``.venv/bin/snakemake``
    after ``make install`` (the venv is not on PATH), plain ``snakemake`` where there is none beside it."""
    exe = Path(sys.executable).parent / "snakemake"
    if not exe.is_file():
        return "snakemake"
    exe = exe.absolute()
    try:
        return exe.relative_to(workdir.resolve()).as_posix()
    except ValueError:
        return str(exe)


def heal(workdir: str | os.PathLike = ".", results: str = "results") -> tuple[int, list[str]]:
    """Run the steps of the module docstring in ``workdir``; returns (exit status, lines to print)."""
    wd = Path(workdir)
    if locked(wd):
        return 1, [f"{wd / LOCKS} holds a lock: a snakemake run is active in {wd.resolve()}, or one was killed "
                   "(kill -9, a closed terminal, power loss); wait for it to end, or if none runs, "
                   f"run `{snakemake_command(wd)} --unlock` (with the same --configfile), then `make reproduce` "
                   "again"]
    res = wd / results
    lines = stop_orphans(wd) + remove_temporaries(res, wd) + remove_damaged(res, wd)
    if lines:
        lines += forget_subspaces(res, wd)
    problems = unwritable(res, wd)
    return (1 if problems else 0), lines + problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="jointid results",
        description="heal: before a run, stop orphaned jobs of a killed snakemake, remove stale temporary files "
                    "and damaged results (checked against their provenance sidecars), check that results/ is "
                    "writable. `make reproduce` runs it before Snakemake.")
    parser.add_argument("command", choices=["heal"])
    parser.add_argument("--workdir", default=".", help="the workflow folder (default: the current one)")
    args = parser.parse_args(argv)
    status, lines = heal(args.workdir)
    for line in lines:
        print(f"jointid results heal: {line}", file=sys.stderr if status else sys.stdout)
    return status


if __name__ == "__main__":
    sys.exit(main())
