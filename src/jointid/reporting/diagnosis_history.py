"""The run history ``results/history.csv``: one row per diagnosis run (docs/effects.md).

Each row holds the run's time stamp, config hash, dataset, the current model variant, its errors and
the verdict; :func:`append_history` adds a row under a file lock (``<csv>.lock``, :mod:`filelock`),
so parallel runs never interleave.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np
from filelock import FileLock

from jointid.correlate import pairing as correlate
from jointid.diagnosis.loop import Diagnosis


def history_row(res: Diagnosis, dataset: str, cfg_hash: str) -> dict:
    """One row of ``results/history.csv`` for this run: the current model's errors, the verdict and
    what the data identify of the current model's contact law (``identified``; empty without one)."""
    cur = res.current[res.current.status == "paired"]
    summ = correlate.error_summary(res.current)
    errs = "; ".join(f"{r.state}: max {r.max_abs_error_pct:.3f} % rms {r.rms_error_pct:.3f} %"
                     if np.isfinite(r.max_abs_error_pct) else f"{r.state}: no paired mode"
                     for r in summ.itertuples())
    variant = res.ladder["variant"].iloc[-1] if len(res.ladder) else "baseline"
    non_sugg = [v for v in dict.fromkeys(res.ladder["variant"]) if "(" not in v]  # not a suggestion
    variant = non_sugg[-1] if non_sugg else variant
    e = cur["error_pct"].to_numpy(float)
    return {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": cfg_hash,
            "dataset": dataset, "variant": variant,
            "max_abs_error_pct": float(np.abs(e).max()) if len(e) else "",
            "rms_error_pct": float(np.sqrt(np.mean(e ** 2))) if len(e) else "",
            "errors": errs, "verdict": res.explained_by,
            "identified": res.identifiable.get("current", "")}


def append_history(path, row: dict) -> None:
    """Append ``row`` to the CSV ``path`` (header written once; a file lock guards parallel runs).

    Parameters
    ----------
    path : str or Path
        The history CSV; created with its folder.  An existing file's header fixes the columns
        (keys of ``row`` outside it are dropped).
    row : dict
        Column name to value.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(f"{path}.lock"), open(path, "a+", newline="") as fh:
        fh.seek(0)
        first = fh.readline()
        header = first.strip().split(",") if first else list(row)
        fh.seek(0, 2)
        w = csv.DictWriter(fh, fieldnames=header, extrasaction="ignore", lineterminator="\n")
        if not first:
            w.writeheader()
        w.writerow(row)
