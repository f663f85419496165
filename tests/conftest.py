"""Shared helpers for the workflow tests: run Snakemake on a copy of the workflow in a temp folder.

The workflow (Snakefile, config.yaml, workflow/, data/) is copied into a fresh folder and Snakemake
runs there with ``--configfile config.yaml <repo>/tests/coarse_config.yaml <repo>/tests/coarse_run.yaml``
(plus any extra config files a test adds), never in the repository's own ``results/``.  The Snakemake executable is the
one next to ``sys.executable`` (the test venv).

Fixtures
--------
coarse_run (session)
    A folder holding one complete, uninterrupted coarse run (``snakemake -j2``).  Tests must not
    modify it: clone it with :func:`clone_run` first.
resumed_run (session)
    A second run of the same workflow from a clean folder, killed (the whole process group, SIGKILL)
    as soon as the first DOE point is written, then unlocked and resumed with
    ``--rerun-incomplete`` up to the first response surface (:data:`RESUMED_TARGETS`).  The
    interruption tests check what the kill left; the determinism tests compare its results with
    ``coarse_run``'s.  One run serves both.
second_run (session, ``make test-all`` only)
    A second complete coarse run from a clean folder, uninterrupted: the whole workflow's results
    are compared with ``coarse_run``'s, byte for byte.

BLAS/OpenMP libraries run single-threaded in the tests (set here before numpy is imported, inherited
by the Snakemake runs): the machine's cores are shared by parallel jobs.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# the dataset checks' cache (jointid.data.checked) of this test session, not the user's
if "JOINTID_CACHE_DIR" not in os.environ:
    import tempfile

    os.environ["JOINTID_CACHE_DIR"] = tempfile.mkdtemp(prefix="jointid-test-cache-")

import fnmatch  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
COARSE_CONFIG = REPO / "tests" / "coarse_config.yaml"
COARSE_RUN = REPO / "tests" / "coarse_run.yaml"  # the workflow runs' lighter diagnosis (its comment says why)
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
WORKFLOW_ITEMS = ("Snakefile", "config.yaml", "workflow", "data")
CORE_RULES = ("mesh", "doe", "modal", "gather_modal", "fit_surface", "scout", "doe_zoom", "modal_zoom",
              "gather_zoom", "fit_zoom", "identify", "verify", "tables")
STATES = ("power_off", "power_on")
TABLES = ("results/tables/table2_power_off.csv", "results/tables/table3_power_on.csv")
# what the resumed run is resumed to: the first response surface (mesh, DOE solves, gathered
# modes, surface fit).  The rest of the chain is left out (about 250 core-s of CI; the edge-level
# meshes are temp() files, gone in the reference run); tests/test_determinism.py runs the whole
# workflow twice under `make test-all`.
RESUMED_TARGETS = ("results/surface/model.json",)
TABLE_COLUMNS = ["order", "experimental_Hz", "simulation_Hz", "relative_error_pct",
                 "paper_simulation_Hz", "paper_relative_error_pct"]
# A whole coarse run takes about 10 minutes on the 2-core machine when it has the cores to itself, several
# times that beside another long job: the limit only catches a hung run, so it is generous (40 minutes),
# and JOINTID_TEST_TIMEOUT_SCALE (a number, default 1) scales it on a slower or busier machine.
RUN_TIMEOUT_S = 2400 * float(os.environ.get("JOINTID_TEST_TIMEOUT_SCALE", "1"))


# ------------------------------------------------------------------ two workers (make test: pytest -n 2)
# ``make test`` runs the tests in two pytest-xdist workers.  Each worker takes whole groups: a test
# file (its module fixtures, e.g. the hidden-effect cases' shared solver, are built once), and the
# files of the shared coarse reference run (session fixtures ``coarse_run``/``resumed_run``, built
# once per worker that uses them) as one group.  Groups are handed out in collection order, the
# slowest first: seconds of the slowest groups in `make test` (test time summed per group in CI on the 2-core Intel
# Xeon, session 82; the two marked: make test-all); they only order the work (the longest first, so that the
# two workers end together).
SHARED_RUN_FILES = ("test_api_method.py", "test_determinism.py", "test_faults.py", "test_interrupt.py", "test_reruns.py", "test_report.py",
                    "test_workflow_e2e.py")
GROUP_SECONDS = {"coarse_run": 276, "test_shape_residuals.py": 93, "test_mesh_error.py": 54, "test_diagnosis_basis.py": 47,
                 "test_example_hammer_test.py": 40, "test_diagnose.py": 39, "test_ema.py": 36, "test_rom.py": 28,
                 "test_examples.py": 27, "test_affine_materials.py": 21, "test_damping_in_table1.py": 21,
                 "test_doe_modes.py": 18, "test_ambiguity.py": 17, "test_model_error_cases.py": 16, "test_warmstart.py": 14,
                 "test_hidden_effects.py": 14, "test_memo.py": 14, "test_hypotheses_affine.py": 13, "test_patch.py": 12,
                 "test_blockrigidity.py": 11, "test_fem.py": 10, "test_checks.py": 10,
                 "test_meshin_workflow.py": 106, "test_example_single_carriage.py": 200}  # these two: make test-all


def test_group(nodeid: str) -> str:
    """The worker group of a test (by its node id): ``coarse_run`` or its file name."""
    name = Path(nodeid.split("::", 1)[0]).name
    return "coarse_run" if name in SHARED_RUN_FILES else name


def pytest_collection_modifyitems(config, items):
    """The slowest groups first (the order is otherwise kept)."""
    items.sort(key=lambda item: -GROUP_SECONDS.get(test_group(item.nodeid), 0))


def pytest_xdist_make_scheduler(config, log):
    """pytest-xdist: hand out whole groups (:func:`test_group`), in collection order."""
    from xdist.scheduler import LoadScopeScheduling

    class GroupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return test_group(nodeid)

    config.option.loadscopereorder = False
    return GroupScheduling(config, log)


# ------------------------------------------------------------------ diagnosis on synthetic data
def diagnosis_rig() -> dict:
    """The rig of the synthetic diagnosis tests: coarse mesh, normal and lateral joint stiffness
    identified, feed stiffness fixed (so the feed effect is not absorbed by an identified parameter).
    Returns ``{"cfg", "settings", "model", "system", "solver"}`` (solver None: the first diagnosis makes it;
    ``cfg``: the validated configuration, ``settings`` its
    :class:`~jointid.config.typed_diagnosis.DiagnosisSettings`)."""
    from jointid.config.synthetic import identification_config
    from jointid.config.typed_diagnosis import DiagnosisSettings
    from jointid.synthetic.generate import identification_rig

    cfg = identification_config(coarse_config_dict())
    return {"cfg": cfg, **identification_rig(DiagnosisSettings.from_config(cfg))}


def truth_settings(truth: dict, cfg: dict):
    """The :class:`~jointid.config.typed_diagnosis.DiagnosisSettings` of a truth model: ``cfg`` with the
    truth's overrides (:func:`jointid.config.synthetic.truth_config`), as the synthetic generator takes them."""
    from jointid.config.synthetic import truth_config
    from jointid.config.typed_diagnosis import DiagnosisSettings

    return DiagnosisSettings.from_config(truth_config(truth, cfg))


def ladder_text(ladder) -> str:
    """``baseline 8.10 % -> +effect (suggested) 0.40 %``: the largest state error along a ladder."""
    g = ladder.groupby("variant", sort=False)["max_abs_error_pct"].max()
    return " -> ".join(f"{v} {m:.2f} %" for v, m in g.items())


def print_summary(summary: dict, capsys) -> None:
    """Print a synthetic-case summary (one row per case) and each case's verdict text (pytest -s);
    skip when no case ran."""
    import pandas as pd

    if not summary:
        pytest.skip("no case ran")
    df = pd.DataFrame(summary).T
    with capsys.disabled():
        print("\n" + df.drop(columns="text").to_string())
        for name, text in df["text"].items():
            print(f"\n{name}: {text}")


# ------------------------------------------------------------------ workflow copies
def coarse_config_dict(*overlays: Path) -> dict:
    """The default ``config.yaml`` with the sections of ``tests/coarse_config.yaml`` (then of each of
    ``overlays``) merged over it (one level deep, as Snakemake merges config files), as a plain dict — not
    yet validated.  ``coarse_config_dict(COARSE_RUN)`` is the configuration of the tests' Snakemake runs."""
    import yaml

    with open(REPO / "config.yaml") as fh:
        cfg = yaml.safe_load(fh)
    for path in (COARSE_CONFIG, *overlays):
        with open(path) as fh:
            for k, v in yaml.safe_load(fh).items():
                cfg[k] = {**cfg.get(k, {}), **v}
    return cfg


def copy_workflow(dest: Path) -> Path:
    """Copy Snakefile, config.yaml, workflow/ and data/ of the repository into ``dest``."""
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".snakemake")
    for item in WORKFLOW_ITEMS:
        src = REPO / item
        if src.is_dir():
            shutil.copytree(src, dest / item, ignore=ignore)
        else:
            shutil.copy2(src, dest / item)
    return dest


def clone_run(src: Path, dest: Path) -> Path:
    """Copy a whole run folder (results, logs, .snakemake metadata), keeping file times."""
    shutil.copytree(src, dest, symlinks=True)
    return Path(dest)


def write_config(path: Path, text: str) -> Path:
    """Write an extra YAML config file (merged after the coarse config)."""
    path = Path(path)
    path.write_text(text)
    return path


def snakemake_cmd(*args: str, configs=()) -> list[str]:
    """``snakemake <args> --configfile config.yaml <coarse> <coarse run> <configs...>`` (configfile last)."""
    return [str(SNAKEMAKE), *args, "--configfile", "config.yaml", str(COARSE_CONFIG), str(COARSE_RUN),
            *[str(c) for c in configs]]


def run_snakemake(workdir: Path, *args: str, configs=(), timeout: float = RUN_TIMEOUT_S,
                  check: bool = False) -> subprocess.CompletedProcess:
    """Run Snakemake in ``workdir``; returns the completed process (text stdout/stderr).

    With ``check=True`` a non-zero exit fails the test, showing the end of the output.
    """
    proc = subprocess.run(snakemake_cmd(*args, configs=configs), cwd=workdir, capture_output=True,
                          text=True, timeout=timeout, env=workflow_env())
    if check and proc.returncode != 0:
        pytest.fail(f"snakemake {' '.join(args)} failed (exit {proc.returncode}) in {workdir}:\n"
                    + tail(proc.stdout + proc.stderr))
    return proc


def run_example(name: str, *args: str, timeout: float = 300) -> tuple[str, float]:
    """Run ``docs/examples/<name> <args>`` from the repository root as a user would (the test venv's Python,
    BLAS single-threaded); its standard output and its time in s.  A failed run fails the test."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, str(REPO / "docs" / "examples" / name), *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)
    seconds = time.perf_counter() - t0
    assert proc.returncode == 0, f"{name} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    print(f"{name}: {seconds:.1f} s")
    return proc.stdout, seconds


def workflow_env() -> dict:
    env = dict(os.environ)
    env["PATH"] = str(SNAKEMAKE.parent) + os.pathsep + env.get("PATH", "")
    return env


def tail(text: str, n: int = 40) -> str:
    return "\n".join(text.splitlines()[-n:])


# ------------------------------------------------------------------ dry-run parsing
_STATS_ROW = re.compile(r"^\s*([A-Za-z_][\w]*)\s+(\d+)\s*$")


def scheduled_jobs(output: str) -> dict[str, int]:
    """Jobs per rule from the first ``Job stats:`` table of a (dry-)run's output; {} if none.

    The ``all`` and ``total`` rows are dropped.
    """
    lines = output.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == "Job stats:")
    except StopIteration:
        return {}
    jobs: dict[str, int] = {}
    for line in lines[start + 1:]:
        if not line.strip():
            if jobs:
                break
            continue
        m = _STATS_ROW.match(line)
        if m and m.group(1) not in ("job", "total", "all"):
            jobs[m.group(1)] = int(m.group(2))
        elif jobs and not m and not set(line.strip()) <= set("- "):
            break
    return jobs


def extra_rule_names(workdir: Path = REPO) -> set[str]:
    """Rules defined in the included rule files ``workflow/rules/*.smk``."""
    names = set()
    for smk in sorted(Path(workdir, "workflow", "rules").glob("*.smk")):
        names.update(re.findall(r"^\s*rule\s+(\w+)\s*:", smk.read_text(), flags=re.M))
    return names


# ------------------------------------------------------------------ file checks
def file_hashes(root: Path, patterns=("results/**/*",)) -> dict[str, str]:
    """{relative path: sha256} of the files under ``root`` matching the glob patterns."""
    root = Path(root)
    out = {}
    for pat in patterns:
        for p in sorted(root.glob(pat)):
            if p.is_file():
                out[p.relative_to(root).as_posix()] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


# Result files that legitimately hold wall-clock time (run time stamps, timings): compared after
# :func:`normalised` removes it.  Provenance sidecars (``*.provenance.json``) are compared by
# their reproducible fields (tests/test_determinism.py).
WALL_CLOCK = ("results/history.csv", "results/diagnosis/*/verdict.json", "results/diagnosis/*/index.html")
_TIMESTAMP = re.compile(rb"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z")
_SECONDS = re.compile(rb"\b\d+(\.\d+)? s\b")  # durations, e.g. "model 20688 DOFs, 13 s."
_TIME_KEYS = {"time_utc", "timestamp_utc", "timing_s"}


def is_wall_clock(rel: str) -> bool:
    return any(fnmatch.fnmatch(rel, pat) for pat in WALL_CLOCK)


def normalised(path: Path) -> bytes:
    """A wall-clock file's bytes without time stamps and durations (JSON: without time/timing keys)."""
    data = Path(path).read_bytes()
    if Path(path).suffix == ".json":
        def strip(obj):
            if isinstance(obj, dict):
                return {k: strip(v) for k, v in obj.items() if k not in _TIME_KEYS}
            if isinstance(obj, list):
                return [strip(v) for v in obj]
            return obj
        return json.dumps(strip(json.loads(data)), sort_keys=True).encode()
    return _SECONDS.sub(b"<seconds>", _TIMESTAMP.sub(b"<time>", data))


def comparable_hashes(root: Path, patterns=("results/**/*",)) -> dict[str, str]:
    """Like :func:`file_hashes` without provenance sidecars, wall-clock files hashed normalised."""
    root = Path(root)
    out = {}
    for rel, digest in file_hashes(root, patterns).items():
        if rel.endswith(".provenance.json"):
            continue
        out[rel] = hashlib.sha256(normalised(root / rel)).hexdigest() if is_wall_clock(rel) else digest
    return out


def temporary_files(root: Path) -> list[str]:
    """Leftover temporary files (``*.tmp`` names, e.g. from ``jointid.io.atomic_path``) below root."""
    root = Path(root)
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*")
                  if p.is_file() and (p.name.endswith(".tmp") or ".tmp." in p.name))


def incomplete_markers(workdir: Path) -> list[str]:
    """Snakemake's incomplete-output markers left in ``.snakemake/incomplete``."""
    d = Path(workdir, ".snakemake", "incomplete")
    return sorted(p.name for p in d.rglob("*") if p.is_file()) if d.is_dir() else []


def npz_arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def assert_arrays_equal(za: dict, zb: dict, name: str) -> None:
    """Same array names, dtypes, shapes and values (bit for bit)."""
    assert sorted(za) == sorted(zb), f"{name}: arrays {sorted(za)} != {sorted(zb)}"
    for k in za:
        assert za[k].dtype == zb[k].dtype and za[k].shape == zb[k].shape, f"{name}:{k} differs in shape/dtype"
        assert np.array_equal(za[k], zb[k]), f"{name}:{k} values differ"


def assert_npz_equal(a: Path, b: Path) -> None:
    assert_arrays_equal(npz_arrays(a), npz_arrays(b), a.name)


# ------------------------------------------------------------------ the reference run
@pytest.fixture(scope="session")
def coarse_run(tmp_path_factory) -> Path:
    """One complete coarse run of the whole workflow (``snakemake -j2``); read-only for tests."""
    wd = copy_workflow(tmp_path_factory.mktemp("coarse_reference"))
    run_snakemake(wd, "-j2", check=True)
    return wd


def group_alive(pgid: int) -> list[int]:
    """Live (non-zombie) processes of a process group."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rfind(")") + 2:].split()
        if fields[0] != "Z" and int(fields[2]) == pgid:
            pids.append(int(stat.parent.name))
    return pids


@dataclass
class ResumedRun:
    """What :func:`resumed_run` saw at the kill, and the folder of the finished, resumed run."""
    workdir: Path
    n_points: int                 # DOE points of the design
    done_at_kill: dict            # point file name -> its arrays, as the kill left them
    tables_at_kill: list          # result tables that existed right after the kill
    survivors: list               # processes of the killed group still alive after the kill


@pytest.fixture(scope="session")
def resumed_run(coarse_run, tmp_path_factory) -> ResumedRun:
    """A second run, killed during the DOE fan-out and resumed to :data:`RESUMED_TARGETS` (see the
    module docstring)."""
    n_points = len(list((coarse_run / "results" / "modal" / "points").glob("*.npz")))
    base = tmp_path_factory.mktemp("resumed")
    wd = copy_workflow(base / "wf")
    points = wd / "results" / "modal" / "points"
    log = open(base / "interrupted.log", "w")
    proc = subprocess.Popen(snakemake_cmd("-j2", *RESUMED_TARGETS), cwd=wd, stdout=log, stderr=subprocess.STDOUT,
                            env=workflow_env(), start_new_session=True)
    try:
        deadline = time.monotonic() + 600
        while not list(points.glob("*.npz")):
            assert proc.poll() is None, "snakemake ended before the DOE fan-out started"
            assert time.monotonic() < deadline, "no modal result within 10 minutes"
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)  # the whole group: snakemake and its running jobs
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        log.close()
    for _ in range(100):
        if not group_alive(proc.pid):
            break
        time.sleep(0.1)
    run = ResumedRun(workdir=wd, n_points=n_points,
                     done_at_kill={p.name: npz_arrays(p) for p in sorted(points.glob("*.npz"))},
                     tables_at_kill=[t for t in TABLES if (wd / t).exists()],
                     survivors=group_alive(proc.pid))
    run_snakemake(wd, "--unlock", check=True)
    run_snakemake(wd, "-j2", "--rerun-incomplete", *RESUMED_TARGETS, check=True)
    yield run
    shutil.rmtree(wd / "results", ignore_errors=True)  # 30+ MB per run: free the shared disk


@pytest.fixture(scope="session")
def second_run(coarse_run, tmp_path_factory) -> Path:
    """A second complete coarse run from a clean folder (``make test-all``: about three minutes)."""
    wd = copy_workflow(tmp_path_factory.mktemp("second_run"))
    run_snakemake(wd, "-j2", check=True)
    yield wd
    shutil.rmtree(wd / "results", ignore_errors=True)
