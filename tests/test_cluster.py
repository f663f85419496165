"""Scale-out: the DOE fan-out through Snakemake's cluster-generic executor and the SLURM profile.

``tests/cluster_submit.sh`` stands in for ``sbatch``: it starts each job script detached in the
background and returns a job id at once, so Snakemake learns the outcome of each job only through
the scheduler interface (job id, jobfinished/jobfailed markers).  The workflow runs with the
settings of ``profiles/slurm`` (resources, retries, keep-going), the executor switched to
cluster-generic.  To stay fast the DOE is cut to one identified parameter (7 modal jobs) on a hex1
coarse mesh; the mechanics are the same for any number of points.  Each cluster job starts its own
Snakemake, so the fan-out test takes ~30 s on 2 cores: it is marked ``slow``.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SUBMIT = ROOT / "tests" / "cluster_submit.sh"
PROFILE = ROOT / "profiles" / "slurm"
SNAKEMAKE = Path(sys.executable).parent / "snakemake"
N_MODES = 6


def _workdir(tmp: Path) -> Path:
    for name in ("Snakefile", "config.yaml", "workflow", "data"):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, tmp / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, tmp / name)
    cfg = yaml.safe_load((tmp / "config.yaml").read_text())
    params = cfg["joints"]["parameters"]
    keep = "k_normal_N_per_m3"
    cfg["joints"]["fixed"] = {n: float(np.sqrt(s["lower"] * s["upper"])) for n, s in params.items() if n != keep}
    cfg["joints"]["parameters"] = {keep: params[keep]}
    cfg["mesh"].update({"element": "hex1", "max_cell_size_m": 0.12, "refine": 1})
    cfg["solver"].update({"n_modes": N_MODES, "method": "full"})  # the fan-out: one job per DOE point
    cfg["doe"].update({"design": "ccf", "n_center": 1, "n_verification": 2})
    (tmp / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return tmp


def _env(tmp: Path) -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{SNAKEMAKE.parent}{os.pathsep}{env.get('PATH', '')}"
    env["CLUSTER_SUBMIT_LOG"] = str(tmp / "submissions.tsv")
    env["CLUSTER_LOG_DIR"] = str(tmp / "cluster_logs")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


@pytest.mark.slow
@pytest.mark.skipif(not SNAKEMAKE.exists(), reason="snakemake is not installed beside this python")
@pytest.mark.extended  # a non-default executor (profiles/cluster); its submit script and profile are checked below
def test_doe_fanout_through_cluster_generic_executor(tmp_path):
    wd = _workdir(tmp_path)
    submit = f"{SUBMIT} --name {{name}} --mem {{resources.mem_mb}} --time {{resources.runtime}} --cpus {{threads}}"
    cmd = [str(SNAKEMAKE), "--profile", str(PROFILE), "--executor", "cluster-generic",
           "--cluster-generic-submit-cmd", submit, "--jobs", "2", "--latency-wait", "5",
           "--seconds-between-status-checks", "1",
           "results/modal/all.csv"]
    proc = subprocess.run(cmd, cwd=wd, env=_env(wd), capture_output=True, text=True, timeout=600)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]

    sheet = pd.read_csv(wd / "results" / "doe" / "points.csv")
    table = pd.read_csv(wd / "results" / "modal" / "all.csv")
    assert len(sheet) == 7
    assert sorted(table["point"].unique()) == sorted(sheet["point"])
    assert (table.groupby("point")["mode"].count() == N_MODES).all()
    assert (table["freq_Hz"] > 0).all()

    subs = pd.read_csv(wd / "submissions.tsv", sep="\t", header=None,
                       names=["job_id", "pid", "name", "mem_mb", "runtime_min", "cpus", "jobscript"])
    counts = subs["name"].value_counts().to_dict()
    # doe and gather_modal are localrules (seconds, no scheduler round trip); their outputs exist above
    assert counts == {"modal": len(sheet), "mesh": 1}, counts
    # every job left Snakemake through the submit command and came back under its external id
    for job_id in subs["job_id"]:
        assert f"external jobid '{job_id}'" in out
        assert (wd / "cluster_logs" / f"{job_id}.out").exists()
    assert subs["job_id"].is_unique and subs["pid"].is_unique
    # declared resources travel with the jobs (Snakefile / profile set-resources)
    modal = subs[subs["name"] == "modal"]
    assert (modal["mem_mb"] == 3000).all() and (modal["cpus"] == 1).all() and (modal["runtime_min"] > 0).all()
    assert int(subs.loc[subs["name"] == "mesh", "mem_mb"].iloc[0]) >= 3000


def test_submit_script_rejects_bad_calls(tmp_path):
    env = _env(tmp_path)
    r = subprocess.run([str(SUBMIT), "--queue", "x", "job.sh"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and "unknown option '--queue'" in r.stderr
    r = subprocess.run([str(SUBMIT), str(tmp_path / "missing.sh")], cwd=tmp_path, env=env, capture_output=True,
                       text=True)
    assert r.returncode == 2 and "not readable" in r.stderr
    assert not (tmp_path / "submissions.tsv").exists()


def test_submit_script_runs_job_detached(tmp_path):
    job = tmp_path / "job.sh"
    job.write_text(f"sleep 0.3; echo done > {tmp_path / 'marker'}\n")
    r = subprocess.run([str(SUBMIT), "--name", "demo", "--mem", "100", str(job)], cwd=tmp_path, env=_env(tmp_path),
                       capture_output=True, text=True, timeout=10)
    assert r.returncode == 0 and r.stdout.startswith("local-")
    assert not (tmp_path / "marker").exists()  # returned before the job finished
    for _ in range(100):
        if (tmp_path / "marker").exists():
            break
        subprocess.run(["sleep", "0.1"])
    assert (tmp_path / "marker").read_text() == "done\n"
    line = (tmp_path / "submissions.tsv").read_text().split("\t")
    assert line[0] == r.stdout.strip() and line[2:4] == ["demo", "100"]


def test_slurm_profile_covers_the_heavy_rules():
    prof = yaml.safe_load((PROFILE / "config.yaml").read_text())
    assert prof["executor"] == "slurm"
    assert {"mem_mb", "runtime"} <= set(prof["default-resources"])
    snakefile = (ROOT / "Snakefile").read_text()
    for rule, res in prof.get("set-resources", {}).items():
        assert f"rule {rule}:" in snakefile, f"profile sets resources of unknown rule {rule}"
        assert res["mem_mb"] > 0 and res["runtime"] > 0
