"""Shared helpers of the benchmarks: configs, subprocess workers, memory sampling, the table."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "out"
PYTHON = sys.executable

# coarse settings used by --quick (same as tests/coarse_config.yaml)
COARSE = {"mesh": {"element": "hex2", "max_cell_size_m": 0.12, "height_cell_fraction": 1.0,
                   "joint_cell_fraction": 1.0, "refine": 1}}


def diagnosis_rig(rig: str = "coarse") -> dict:
    """The rig of the synthetic diagnosis tests (as ``tests/conftest.py::diagnosis_rig``): normal and
    lateral joint stiffness identified (2e11..4e12 N/m^3), feed stiffness fixed at 1e10 N/m^3 (so the
    feed effect is not absorbed by an identified parameter).  ``rig``: ``coarse`` (config.yaml with
    tests/coarse_config.yaml merged over it, one level deep, as Snakemake merges config files) or
    ``default`` (the shipped config.yaml's mesh).  Returns ``{"cfg", "settings", "model", "system", "solver"}``."""
    import yaml

    from jointid.config.synthetic import identification_config
    from jointid.config.typed_diagnosis import DiagnosisSettings
    from jointid.synthetic.generate import identification_rig

    with open(ROOT / "config.yaml") as fh:
        cfg = yaml.safe_load(fh)
    if rig == "coarse":
        with open(ROOT / "tests" / "coarse_config.yaml") as fh:
            for k, v in yaml.safe_load(fh).items():
                cfg[k] = {**cfg.get(k, {}), **v}
    elif rig != "default":
        raise ValueError(f"rig {rig!r}: use coarse or default")
    cfg = identification_config(cfg)
    return {"cfg": cfg, **identification_rig(DiagnosisSettings.from_config(cfg))}


def truth_settings(truth: dict, cfg: dict):
    """The diagnosis settings of a truth model (``cfg`` with the truth's overrides), as the generator takes them."""
    from jointid.config.synthetic import truth_config
    from jointid.config.typed_diagnosis import DiagnosisSettings

    return DiagnosisSettings.from_config(truth_config(truth, cfg))


def worker_env(blas_threads: int | None) -> dict:
    """Environment of a worker: the BLAS thread count pinned (the 2-core machine is shared, and
    threaded OpenBLAS on small dense blocks only spins), the venv first on PATH."""
    env = dict(os.environ)
    if blas_threads:
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
            env[var] = str(blas_threads)
    env["PATH"] = str(Path(PYTHON).parent) + os.pathsep + env.get("PATH", "")
    return env


def run_worker(task: str, args: dict, *, timeout: float | None = None, blas_threads: int | None = 1) -> dict:
    """Run ``python -m benchmarks.worker task args`` in a subprocess; return its JSON result.

    The result holds the worker's own ``peak_rss_MB``; ``wall_s`` (parent-side) is added.
    Raises ``subprocess.TimeoutExpired`` after ``timeout`` seconds (the worker is killed).
    """
    t0 = time.perf_counter()
    proc = subprocess.run([PYTHON, "-m", "benchmarks.worker", task, json.dumps(args)], cwd=ROOT,
                          env=worker_env(blas_threads), capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"worker {task} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    out = json.loads(lines[-1])
    out["wall_s"] = wall
    return out


def _children_map() -> dict[int, list[int]]:
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as fh:
                stat = fh.read()
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        kids.setdefault(ppid, []).append(int(d))
    return kids


def _proc_kB(path: str, key: str) -> int:
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def _rss_kB(pid: int) -> int:
    return _proc_kB(f"/proc/{pid}/status", "VmRSS:")


def _pss_kB(pid: int) -> int:
    """Proportional set size: private pages plus each shared page divided by the number of processes
    mapping it (shared libraries, a memory-mapped model).  Summed over processes it is the memory they
    occupy together; the RSS sum counts every shared page once per process."""
    return _proc_kB(f"/proc/{pid}/smaps_rollup", "Pss:")


class TreeMemorySampler:
    """Samples the summed PSS and RSS of a process and all its descendants (``/proc``, no psutil).

    ``peak_MB`` is the largest PSS sum seen: with parallel jobs it is the memory the machine needed,
    unlike ``ru_maxrss`` (the largest single process).  ``peak_rss_MB`` is the largest RSS sum, which
    counts the pages the processes share (libraries, the memory-mapped model) once per process;
    it equals ``peak_MB`` where nothing is shared, and on kernels without ``smaps_rollup`` it is
    used for ``peak_MB`` too.
    """

    def __init__(self, pid: int, interval_s: float = 0.25):
        self.pid, self.interval = pid, interval_s
        self.peak_kB = 0
        self.peak_rss_kB = 0
        self.has_pss = os.path.exists(f"/proc/{os.getpid()}/smaps_rollup")
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.is_set():
            kids = _children_map()
            todo, pss, rss = [self.pid], 0, 0
            while todo:
                p = todo.pop()
                rss += _rss_kB(p)
                pss += _pss_kB(p) if self.has_pss else 0
                todo.extend(kids.get(p, []))
            self.peak_kB = max(self.peak_kB, pss if self.has_pss else rss)
            self.peak_rss_kB = max(self.peak_rss_kB, rss)
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()

    @property
    def peak_MB(self) -> float:
        return self.peak_kB / 1024.0

    @property
    def peak_rss_MB(self) -> float:
        return self.peak_rss_kB / 1024.0


# ------------------------------------------------------------------ results table
@dataclass
class Row:
    bench: str
    quantity: str
    measured: str
    target: str = ""
    ok: bool | None = None  # None: no target


@dataclass
class Result:
    """One benchmark's rows, notes and raw data (written to ``benchmarks/out/<name>.json``)."""

    name: str
    rows: list[Row] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)

    def add(self, quantity: str, measured: str, target: str = "", ok: bool | None = None) -> None:
        self.rows.append(Row(self.name, quantity, measured, target, ok))


def format_table(results: list[Result]) -> str:
    """One markdown table of all rows, then the notes."""
    head = ["bench", "quantity", "measured", "target", "met"]
    body = []
    for res in results:
        for r in res.rows:
            met = "" if r.ok is None else ("yes" if r.ok else "NO")
            body.append([r.bench, r.quantity, r.measured, r.target, met])
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    line = lambda cells: "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths)) + " |"  # noqa: E731
    out = [line(head), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    out += [line(b) for b in body]
    notes = [f"- ({res.name}) {n}" for res in results for n in res.notes]
    if notes:
        out += ["", "Notes:"] + notes
    return "\n".join(out)


def write_result(res: Result, quick: bool) -> Path:
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{res.name}{'_quick' if quick else ''}.json"
    doc = {"name": res.name, "quick": quick, "rows": [r.__dict__ for r in res.rows], "notes": res.notes,
           "data": res.data, "written": time.strftime("%Y-%m-%d %H:%M:%S")}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=2, default=float) + "\n")
    os.replace(tmp, path)
    return path


def load_result(name: str, quick: bool) -> Result | None:
    """A result saved by :func:`write_result` (None if there is none); its timestamp becomes a note."""
    path = OUT / f"{name}{'_quick' if quick else ''}.json"
    if not path.exists():
        return None
    doc = json.loads(path.read_text())
    res = Result(doc["name"], [Row(**r) for r in doc["rows"]], list(doc["notes"]), doc.get("data", {}))
    res.notes.append(f"measured {doc.get('written', '?')}")
    return res


def fmt_s(t: float) -> str:
    return f"{t:.3g} s" if t >= 0.1 else f"{t * 1e3:.3g} ms"


def fmt_mb(mb: float) -> str:
    """``mb`` MiB (sizes here are counted in 1024s: GNU time's kbytes are KiB) as MiB or GiB."""
    return f"{mb / 1024:.2f} GiB" if mb >= 1024 else f"{mb:.0f} MiB"


WORKFLOW_FILES = ("Snakefile", "config.yaml", "workflow", "data")
"""What a temporary copy of the project needs to run the workflow (the package is installed)."""


def copy_project(prefix: str, quick: bool) -> tuple[Path, list[str]]:
    """A temporary copy of the workflow files; returns its folder and the config files to pass
    (``config.yaml``, plus the coarse test config with ``quick``)."""
    import shutil
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    for name in WORKFLOW_FILES:
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
    return tmp, configs


def head_commit() -> str:
    """The checked-out commit, with ``+changes`` when the working tree differs from it."""
    out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(ROOT), "diff", "--quiet", "HEAD", "--", "src", "Snakefile",
                            "workflow", "config.yaml"]).returncode
    return out.stdout.strip() + ("+changes" if dirty else "")


def copy_commit(commit: str, prefix: str, quick: bool) -> tuple[Path, list[str], str]:
    """The files of ``commit`` (``git archive``) in a temporary folder, its package under ``src/``;
    returns the folder, the config files to pass (as :func:`copy_project`) and the full commit."""
    import tempfile

    full = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", f"{commit}^{{commit}}"],
                          capture_output=True, text=True)
    if full.returncode != 0:
        raise SystemExit(f"--compare {commit}: not a commit of this repository ({full.stderr.strip()})")
    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", full.stdout.strip()],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
    configs = ["config.yaml"] + (["tests/coarse_config.yaml"] if quick else [])
    return tmp, configs, full.stdout.strip()


def machine() -> str:
    """One line: CPU model, cores, memory, OS."""
    import platform

    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor() or "?") if Path("/proc/cpuinfo").exists() else "?"
    mem = _proc_kB("/proc/meminfo", "MemTotal:") / 1024 ** 2
    return f"{cpu}, {os.cpu_count()} cores, {mem:.0f} GiB, {platform.system()} {platform.release()}"
