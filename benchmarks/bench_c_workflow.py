"""(c) The full workflow ``snakemake -j2`` from a clean results directory, in a temporary copy."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from .common import OUT, PYTHON, ROOT, Result, TreeMemorySampler, fmt_mb, worker_env

COPY = ("Snakefile", "config.yaml", "workflow", "data")


def run(quick: bool = False, blas_threads: int | None = 1, keep: bool = False) -> Result:
    res = Result("c")
    tmp = Path(tempfile.mkdtemp(prefix="jointid-bench-c-"))
    for name in COPY:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, tmp / name, ignore=shutil.ignore_patterns("__pycache__"))
        elif src.exists():
            shutil.copy2(src, tmp / name)
    configs = ["config.yaml"]
    if quick:
        (tmp / "tests").mkdir()
        shutil.copy2(ROOT / "tests" / "coarse_config.yaml", tmp / "tests" / "coarse_config.yaml")
        configs.append("tests/coarse_config.yaml")
    snakemake = str(Path(PYTHON).parent / "snakemake")
    cmd = [snakemake, "-j2", "--configfile", *configs]
    time_bin = "/usr/bin/time"
    if Path(time_bin).exists():
        cmd = [time_bin, "-v", *cmd]
    log = tmp / "snakemake.out"
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        proc = subprocess.Popen(cmd, cwd=tmp, env=worker_env(blas_threads), stdout=fh, stderr=subprocess.STDOUT)
        with TreeMemorySampler(proc.pid) as mem:
            rc = proc.wait()
    wall = time.perf_counter() - t0
    text = log.read_text()
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    max_single = int(m.group(1)) / 1024.0 if m else float("nan")
    steps = re.findall(r"(\d+) of (\d+) steps \(100%\) done", text)
    n_jobs = int(steps[-1][1]) if steps else None
    ok = rc == 0
    res.add(f"snakemake -j2 from clean ({n_jobs} jobs{', coarse config' if quick else ''})",
            f"{wall:.1f} s" + ("" if ok else f" (FAILED, exit {rc})"), "<= 120 s", ok and wall <= 120.0)
    res.add("peak memory, all processes together (sampled /proc)", fmt_mb(mem.peak_MB), "<= 4 GB",
            ok and mem.peak_MB <= 4096)
    res.add("peak RSS of the largest single process (time -v)", fmt_mb(max_single))
    per_rule = _rule_times(tmp, quick)
    if per_rule:
        top = sorted(per_rule.items(), key=lambda kv: -kv[1]["sum_s"])[:5]
        res.notes.append("job time by rule (sum over jobs, from the rules' benchmark files): " + ", ".join(
            f"{rule} {v['sum_s']:.0f} s / {v['n']} job{'s' if v['n'] > 1 else ''}" for rule, v in top))
    res.notes.append(f"temporary copy {tmp}{' (kept)' if keep or not ok else ' (removed)'}; "
                     f"BLAS threads per job: {blas_threads or 'default'}")
    res.data = {"wall_s": wall, "exit": rc, "peak_tree_MB": mem.peak_MB, "max_single_MB": max_single,
                "n_jobs": n_jobs, "per_rule": per_rule, "log_tail": text[-4000:]}
    if ok and not keep:
        shutil.rmtree(tmp, ignore_errors=True)
    return res


def _rule_times(workdir: Path, quick: bool) -> dict[str, dict]:
    """Sum of the ``s`` column of the rules' Snakemake benchmark files, by rule; the files are
    copied to ``benchmarks/out/c_rules[_quick]/``."""
    src = workdir / "benchmarks" / "out"
    if not src.is_dir():
        return {}
    dest = OUT / f"c_rules{'_quick' if quick else ''}"
    shutil.rmtree(dest, ignore_errors=True)
    shutil.copytree(src, dest)
    out: dict[str, dict] = {}
    for tsv in sorted(src.rglob("*.tsv")):
        rule = tsv.relative_to(src).parts[0].removesuffix(".tsv")
        lines = tsv.read_text().splitlines()
        if len(lines) < 2:
            continue
        try:
            sec = float(lines[1].split("\t")[0])
        except ValueError:
            continue
        v = out.setdefault(rule, {"sum_s": 0.0, "n": 0})
        v["sum_s"] += sec
        v["n"] += 1
    return out
