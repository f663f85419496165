"""(h) The loop of docs/effects.md: enable one effect in the config and rerun the diagnosis target.

In a temporary copy of the project the diagnosis target is built once from clean (mesh and
diagnosis); then a config overlay enables one effect (``em_preload`` by default, the effect the
paper's data ask for first) and ``snakemake -j2 results/diagnosis/<dataset>/ranking.csv`` runs again.
That second run is the loop a user waits for: its wall time is the figure, with the diagnosis
rule's own time and the errors before and after from ``results/history.csv``.  Before it, the quick
half (``results/diagnosis/<dataset>/current/ladder.csv``: the current model calibrated, no candidate
search) is timed on the same config.

``python -m benchmarks h [--quick]`` (or ``python -m benchmarks.bench_h_loop [--quick] [--keep]``).
"""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
import time
from pathlib import Path

from .common import PYTHON, Result, copy_project, worker_env

EFFECT = "em_preload"
REQUIRED_S = 15.0  # issue 54: the loop at most 15 s (issue 50 asked 60 s, target 20 s: met)


def run(quick: bool = False, blas_threads: int | None = 1, keep: bool = False, effect: str = EFFECT) -> Result:
    res = Result("h")
    tmp, configs = copy_project("jointid-bench-h-", quick)
    target = "results/diagnosis/paper/ranking.csv"
    first = _snakemake(tmp, target, configs, blas_threads, "first.out")
    (tmp / "loop.yaml").write_text(f"effects:\n  {effect}: {{}}\n")
    quick_run = _snakemake(tmp, "results/diagnosis/paper/current/ladder.csv", [*configs, "loop.yaml"],
                           blas_threads, "current.out")
    second = _snakemake(tmp, target, [*configs, "loop.yaml"], blas_threads, "loop.out")
    ok = first["exit"] == 0 and second["exit"] == 0
    wall = second["wall_s"]
    res.add(f"enable {effect}, rerun {target}{' (coarse config)' if quick else ''}",
            f"{wall:.1f} s" + ("" if ok else f" (FAILED, exit {second['exit']})"),
            f"<= {REQUIRED_S:.0f} s", ok and wall <= REQUIRED_S)
    rule_s = _rule_seconds(tmp / "benchmarks" / "out" / "diagnosis" / "paper.tsv")
    res.add("  of which the diagnosis rule (its benchmark file)", f"{rule_s:.1f} s")
    qok = quick_run["exit"] == 0
    res.add("the quick half: same config, rerun results/diagnosis/paper/current/ladder.csv",
            f"{quick_run['wall_s']:.1f} s" + ("" if qok else f" (FAILED, exit {quick_run['exit']})"),
            f"<= {REQUIRED_S:.0f} s", qok and quick_run["wall_s"] <= REQUIRED_S)
    res.add("first build of the same target from clean (mesh + diagnosis)", f"{first['wall_s']:.1f} s")
    rows = _history(tmp / "results" / "history.csv")
    if len(rows) >= 2:
        before, after = rows[-2], rows[-1]
        res.add("current model's max |error| before -> after the loop",
                f"{float(before['max_abs_error_pct']):.2f} % -> {float(after['max_abs_error_pct']):.2f} %")
    res.notes.append(f"temporary copy {tmp}{' (kept)' if keep or not ok else ' (removed)'}; "
                     f"BLAS threads per job: {blas_threads or 'default'}")
    res.data = {"first": first, "loop": second, "current": quick_run, "diagnosis_rule_s": rule_s, "effect": effect}
    if ok and not keep:
        shutil.rmtree(tmp, ignore_errors=True)
    return res


def _snakemake(tmp: Path, target: str, configs: list[str], blas_threads, log_name: str) -> dict:
    snakemake = str(Path(PYTHON).parent / "snakemake")
    cmd = [snakemake, "-j2", target, "--configfile", *configs]
    t0 = time.perf_counter()
    with open(tmp / log_name, "w") as fh:
        rc = subprocess.call(cmd, cwd=tmp, env=worker_env(blas_threads), stdout=fh, stderr=subprocess.STDOUT)
    return {"exit": rc, "wall_s": time.perf_counter() - t0, "log_tail": (tmp / log_name).read_text()[-3000:]}


def _rule_seconds(tsv: Path) -> float:
    try:
        return float(tsv.read_text().splitlines()[1].split("\t")[0])
    except (OSError, IndexError, ValueError):
        return float("nan")


def _history(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


if __name__ == "__main__":  # python -m benchmarks.bench_h_loop [--quick] [--keep]
    from .common import format_table, write_result

    quick = "--quick" in sys.argv[1:]
    result = run(quick=quick, keep="--keep" in sys.argv[1:])
    write_result(result, quick)
    print(format_table([result]))
