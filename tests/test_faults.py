"""Faults in the middle of a run (issue 51): each ends in a complete, byte-identical rebuild by the README's
command (here its coarse equivalent: ``jointid results heal`` then ``snakemake -j2 --rerun-incomplete``)
or in a one-line error naming the file; no run exits 0 with an artifact missing.

How the faults are made:

- ``kill -9``: SIGKILL to a job (found by its ticket, :mod:`jointid.stages.jobs`), to ``snakemake``
  alone, or to the whole process group while ``matrices.npz``, the largest file, is being written.
- Damaged results: a file cut to half its size.
- Full disk and permission: the writer's fault hook ``JOINTID_INJECT_FAULT=ENOSPC:<glob>`` (or
  ``EACCES``) raises the ``OSError`` after the data are written, as the real fault would.  The tests
  run as root in CI (permissions do not bite) and cannot mount a small file system.

The end-to-end cases clone the session's coarse run (``coarse_run``) and rebuild only what the fault
touched.  ``make test`` keeps one of each kind (a job and snakemake killed; a fresh run killed while
the largest file is written, its temporary file healed and the file rebuilt; three truncated results;
a full disk); ``extended``: snakemake killed alone, the whole run killed while the largest file is
written in a complete folder (the whole chain is rebuilt), a denied write end to end.
"""

from __future__ import annotations

import fnmatch
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import (RUN_TIMEOUT_S, SNAKEMAKE, clone_run, comparable_hashes, copy_workflow, group_alive,
                      incomplete_markers, run_snakemake, scheduled_jobs, snakemake_cmd, tail, temporary_files,
                      workflow_env)
from jointid import io
from jointid.config import ConfigStamp
from jointid.io_errors import FAULT_ENV, ResultReadError, ResultWriteError
from jointid.reporting.provenance import check_sidecar, provenance_path, write_provenance
from jointid.stages import jobs, recovery

JOINTID = SNAKEMAKE.with_name("jointid")
# written beside the declared outputs, on purpose different after a rerun (the run log and the
# diagnosis's kept basis, the start of its next run): not artifacts of the run
SIDE_FILES = ("results/history.csv", "results/history.csv.lock", "results/diagnosis/*/subspace.npz",
              "results/diagnosis/*/subspace.basis-*.npy")


# ------------------------------------------------------------------ helpers
def artifacts(root: Path) -> dict[str, str]:
    """{relative path: hash} of a run's results, wall-clock files normalised, sidecars and side files left out."""
    return {rel: h for rel, h in comparable_hashes(root).items()
            if not any(fnmatch.fnmatch(rel, pat) for pat in SIDE_FILES)}


def reproduce(wd: Path, env: dict | None = None) -> tuple[int, str]:
    """``make reproduce`` on the coarse configuration: heal, then snakemake; (exit status, all output)."""
    env = {**workflow_env(), **(env or {})}
    heal = subprocess.run([str(JOINTID), "results", "heal"], cwd=wd, capture_output=True, text=True, env=env,
                          timeout=120)
    if heal.returncode:
        return heal.returncode, heal.stdout + heal.stderr
    run = subprocess.run(snakemake_cmd("-j2", "--rerun-incomplete"), cwd=wd, capture_output=True, text=True,
                         env=env, timeout=RUN_TIMEOUT_S)
    return run.returncode, heal.stdout + heal.stderr + run.stdout + run.stderr


def assert_rebuilt(wd: Path, ref: Path, rc: int, out: str, diagnosis_reran: bool = False) -> None:
    """The run ended well, and its results equal the reference run's file for file, with no leftovers.

    ``diagnosis_reran``: the diagnosis ran again in the same folder, from the subspace its first run
    kept (``diagnosis.reuse_subspace``, on by default).  Such a run is documented to agree with one from
    clean to the solver's tolerance, not bit for bit (docs/config-reference.md): its files must exist and
    rank the same effects; every other file stays byte-identical."""
    assert rc == 0, f"the rebuild failed (exit {rc}):\n{tail(out)}"
    got, want = artifacts(wd), artifacts(ref)
    assert sorted(set(want) - set(got)) == [], "artifacts missing after a run that exited 0"
    warm = "results/diagnosis/*" if diagnosis_reran else ""
    assert [k for k in want if got[k] != want[k] and not fnmatch.fnmatch(k, warm)] == [], \
        "artifacts differ from the uninterrupted run's"
    for ranking in (ref / "results" / "diagnosis").glob("*/ranking.csv") if diagnosis_reran else []:
        effects = [io.read_csv(p)["effect"].tolist() for p in (ranking, wd / ranking.relative_to(ref))]
        assert effects[0] == effects[1], f"{ranking.parent.name}: the diagnosis ranks other effects"
    assert temporary_files(wd / "results") == [] and incomplete_markers(wd) == []
    assert jobs.running(wd) == []


def lines_with(text: str, needle: str) -> list[str]:
    return [line for line in text.splitlines() if needle in line]


def wait_for(predicate, proc: subprocess.Popen, what: str, timeout_s: float = 300.0):
    deadline = time.monotonic() + timeout_s
    while True:
        got = predicate()
        if got:
            return got
        assert proc.poll() is None, f"snakemake ended before {what}"
        assert time.monotonic() < deadline, f"no {what} within {timeout_s:.0f} s"
        time.sleep(0.02)


def start(wd: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen(snakemake_cmd("-j2", *args), cwd=wd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=workflow_env(), start_new_session=True)


def job_of(wd: Path, rule: str, output_part: str = "") -> dict | None:
    return next((r for r in jobs.running(wd) if r["rule"] == rule and any(output_part in o for o in r["outputs"])),
                None)


def cut_to_half(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


@pytest.fixture
def clone(coarse_run, tmp_path) -> Path:
    wd = clone_run(coarse_run, tmp_path / "wf")
    yield wd
    for rec in jobs.running(wd):  # never leave a job of a test behind
        jobs.stop(rec, timeout_s=5)


# ------------------------------------------------------------------ writers (no workflow)
@pytest.mark.parametrize("code, words", [("ENOSPC", "no space left on the device (it needs about 17 bytes, "),
                                         ("EDQUOT", "disk quota exceeded"),
                                         ("EACCES", "permission denied"),
                                         ("EROFS", "read-only file system")])
def test_a_failed_write_is_one_line_naming_the_file_and_keeps_the_old_result(tmp_path, monkeypatch, code, words):
    target = tmp_path / "tables" / "table2_power_off.csv"
    io.write_text(target, "old\n")
    monkeypatch.setenv(FAULT_ENV, f"{code}:*/table2_power_off.csv")
    with pytest.raises(ResultWriteError) as err:
        io.write_json(target, {"order": 1})
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"cannot write {target}: {words}"), msg
    assert msg.endswith("then run `make reproduce` again"), msg
    assert target.read_text() == "old\n" and temporary_files(tmp_path) == []


def test_a_failed_write_says_the_space_it_needs(tmp_path, monkeypatch):
    monkeypatch.setenv(FAULT_ENV, "ENOSPC:*.npz")
    with pytest.raises(ResultWriteError, match=r"it needs about 8\.0 MB, [\d.]+ MB free there"):
        io.write_npz(tmp_path / "modes.npz", phi=np.zeros(1_000_000))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name, reader", [("params.json", io.read_json), ("all.csv", io.read_csv),
                                          ("all.npz", io.load_npz), ("all.npz", io.map_npz)])
def test_a_damaged_result_is_named_when_read(tmp_path, name, reader):
    path = tmp_path / name
    if name.endswith(".json"):
        io.write_json(path, {"theta": [1.0, 2.0, 3.0]})
    elif name.endswith(".csv"):
        path.write_bytes(b'order,freq_Hz\n1,"20')  # cut inside a quoted field
    else:
        io.write_npz(path, freqs_Hz=np.arange(100.0))
    if not name.endswith(".csv"):
        cut_to_half(path)
    with pytest.raises(ResultReadError) as err:
        reader(path)
    msg = str(err.value)
    assert msg.startswith(f"cannot read {path}: ") and "make reproduce" in msg and "\n" not in msg, msg


def test_stale_temporaries_below_a_folder_are_removed_and_live_ones_kept(tmp_path):
    host = io._host_tag()
    dead = tmp_path / "model" / f".matrices.npz.p{2**22 + 7}h{host}_ab12.tmp"  # above pid_max: no such process
    live = tmp_path / "identify" / "power_on" / f".params.json.p{os.getppid()}h{host}_cd34.tmp"
    other = tmp_path / "model" / ".hidden_notes.tmp"  # not a writer's temporary file
    for p in (dead, live, other):
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"x" * 1000)
    assert io.remove_stale_below(tmp_path) == [dead]
    assert live.exists() and other.exists()


def test_the_temporary_file_of_a_killed_writer_not_yet_reaped_is_stale(tmp_path):
    """A writer killed with SIGKILL stays a zombie until its parent (or an init that reaps late, as in
    many containers) reaps it: it writes nothing more, so its temporary file is removed."""
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        proc.kill()
        deadline = time.monotonic() + 10
        while Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
            assert time.monotonic() < deadline, "the killed process did not become a zombie"
            time.sleep(0.01)
        tmp = tmp_path / "model" / f".matrices.npz.p{proc.pid}h{io._host_tag()}_ab12.tmp"
        tmp.parent.mkdir()
        tmp.write_bytes(b"x" * 1000)
        assert io.remove_stale_below(tmp_path) == [tmp]
    finally:
        proc.wait()


# ------------------------------------------------------------------ sidecars and heal (no workflow)
def _result_with_sidecar(folder: Path) -> Path:
    out = folder / "results" / "surface" / "model.json"
    io.write_json(out, {"coefficients": [1.0, 2.0]})
    write_provenance(out, ConfigStamp.of({"surface": {}}), inputs=[])
    return out


def test_heal_removes_a_result_that_differs_from_its_sidecar(tmp_path):
    out = _result_with_sidecar(tmp_path)
    good = tmp_path / "results" / "tables" / "table2_power_off.csv"
    io.write_text(good, "order\n1\n")
    write_provenance(good, ConfigStamp.of({}), inputs=[])
    assert check_sidecar(out) is None
    cut_to_half(out)
    assert "differs from the one model.json.provenance.json recorded" in check_sidecar(out)
    status, lines = recovery.heal(tmp_path)
    assert status == 0 and len(lines) == 1 and lines[0].startswith("removed damaged results/surface/model.json: ")
    assert not out.exists() and not provenance_path(out).exists() and good.exists()


def test_heal_forgets_the_kept_subspaces_only_when_it_repaired_something(tmp_path):
    """A kept diagnosis subspace survives a heal with nothing to repair (the loop's reruns start from it)
    and goes with any repair (the rebuilt diagnosis starts afresh, byte-identical to a run from clean)."""
    kept = tmp_path / "results" / "diagnosis" / "paper" / "subspace.npz"
    io.write_text(kept, "records")
    kept_basis = kept.with_name("subspace.basis-0123456789abcdef.npy")  # its basis, kept apart (jointid.fe.warmstart)
    io.write_text(kept_basis, "basis")
    out = _result_with_sidecar(tmp_path)
    assert recovery.heal(tmp_path) == (0, []) and kept.exists() and kept_basis.exists()
    cut_to_half(out)
    status, lines = recovery.heal(tmp_path)
    assert status == 0 and len(lines) == 2 and lines[0].startswith("removed damaged results/surface/model.json")
    assert lines[1].startswith("removed 1 kept diagnosis subspace(s) (results/diagnosis/paper/subspace.npz)")
    assert not kept.exists() and not kept_basis.exists()


def test_heal_removes_a_result_whose_sidecar_is_damaged(tmp_path):
    out = _result_with_sidecar(tmp_path)
    cut_to_half(provenance_path(out))
    status, lines = recovery.heal(tmp_path)
    assert status == 0 and "provenance record model.json.provenance.json is damaged" in lines[0]
    assert not out.exists()


def test_heal_refuses_while_snakemake_holds_the_lock(tmp_path):
    out = _result_with_sidecar(tmp_path)
    cut_to_half(out)
    (tmp_path / ".snakemake" / "locks").mkdir(parents=True)
    (tmp_path / ".snakemake" / "locks" / "0.output.lock").write_text("results/surface/model.json\n")
    status, lines = recovery.heal(tmp_path)
    # the snakemake of the venv by its path: `make install` does not put .venv/bin on PATH
    assert status == 1 and len(lines) == 1 and f"run `{SNAKEMAKE} --unlock`" in lines[0], lines
    assert out.exists(), "nothing is touched while a run may be writing"


def test_heal_stops_at_a_folder_it_cannot_write(tmp_path, monkeypatch):
    _result_with_sidecar(tmp_path)
    locked_dir = str(tmp_path / "results" / "surface")
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == locked_dir else real(p, mode))
    status, lines = recovery.heal(tmp_path)
    assert status == 1 and lines == ["cannot write in results/surface: permission denied or a read-only file "
                                     "system; make it writable (chmod u+w results/surface), then run `make reproduce` "
                                     "again"]


ORPHAN = textwrap.dedent("""
    import sys, time
    from types import SimpleNamespace
    from jointid.io import atomic_path
    from jointid.stages.runner import run_script

    def stage(cfg, inp, out):
        with atomic_path(out[0]) as tmp:
            tmp.write_bytes(b"half of a result")
            print(tmp, file=sys.__stdout__, flush=True)
            while True:  # short sleeps, as a job computes (tests/test_interrupt.py, SIGTERM_STAGE)
                time.sleep(0.1)

    run_script(SimpleNamespace(log=[sys.argv[2]], params=SimpleNamespace(cfg={}), input=[], output=[sys.argv[1]],
                               rule="identify"), stage)
""")


def test_heal_stops_a_job_whose_snakemake_is_gone(tmp_path):
    target = tmp_path / "results" / "identify" / "power_on" / "params.json"
    target.parent.mkdir(parents=True)
    proc = subprocess.Popen([sys.executable, "-c", ORPHAN, str(target.relative_to(tmp_path)), "job.log"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        tmp = tmp_path / proc.stdout.readline().strip()
        assert tmp.is_file() and len(jobs.running(tmp_path)) == 1
        status, lines = recovery.heal(tmp_path)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
    assert status == 0 and len(lines) == 1, lines
    assert lines[0].startswith(f"job identify (pid {proc.pid}, started ") and "stopped (SIGTERM)" in lines[0]
    assert not tmp.exists() and not target.exists() and jobs.running(tmp_path) == []


def test_a_dead_jobs_ticket_is_not_an_orphan(tmp_path):
    folder = tmp_path / jobs.JOBS_DIR
    folder.mkdir(parents=True)
    (folder / "vm_1.json").write_text(json.dumps({"pid": 2**22 + 9, "host": jobs._host(), "start_ticks": "1",
                                                  "rule": "mesh", "outputs": [], "started_utc": "-"}))
    assert jobs.running(tmp_path) == [] and list(folder.iterdir()) == []


UNEXPECTED = textwrap.dedent("""
    import sys
    from types import SimpleNamespace
    from jointid.stages.runner import run_script

    def stage(cfg, inp, out):
        return {}["k_normal_N_per_m3"]

    run_script(SimpleNamespace(log=[sys.argv[1]], params=SimpleNamespace(cfg={}), input=[], output=[],
                               rule="verify"), stage)
""")


SUCCEEDS = textwrap.dedent("""
    import sys
    from types import SimpleNamespace
    from jointid.stages.runner import run_script

    def stage(cfg, inp, out):
        print("stage: the result written")
        with open(out[0], "w") as fh:
            fh.write("order\\n1\\n")

    run_script(SimpleNamespace(log=[sys.argv[1]], params=SimpleNamespace(cfg={}), input=[], output=[sys.argv[2]],
                               rule="verify"), stage)
    print("after run_script")  # not reached: a job that succeeded ends its process there
""")


def test_a_job_that_succeeded_ends_its_process_with_its_log_and_outputs_written(tmp_path):
    log, out = tmp_path / "verify.log", tmp_path / "verify.csv"
    proc = subprocess.run([sys.executable, "-c", SUCCEEDS, str(log), str(out)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text() == "order\n1\n" and provenance_path(out).is_file()
    assert "stage: the result written" in log.read_text() and "after run_script" not in proc.stdout + proc.stderr


def test_an_unexpected_error_is_one_line_on_screen_and_its_traceback_in_the_log(tmp_path):
    log = tmp_path / "verify.log"
    proc = subprocess.run([sys.executable, "-c", UNEXPECTED, str(log)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [
        f"error in rule verify: unexpected KeyError: 'k_normal_N_per_m3'; the full traceback is in {log}"]
    assert "Traceback (most recent call last)" in log.read_text() and "KeyError" in log.read_text()


# ------------------------------------------------------------------ the workflow
@pytest.mark.slow
def test_a_missing_intermediate_result_is_rebuilt_not_ignored(clone):
    """The reported bug: Snakemake does not rebuild a missing file whose consumers are up to date; the
    default target names every result, so it does (dry run)."""
    for rel in ("results/identify/power_on/params.json", "results/modal/all.npz", "results/doe/points.csv",
                "results/harmonic/power_off/modes.npz", "results/diagnosis/paper/verdict.json"):
        (clone / rel).unlink()
    dry = run_snakemake(clone, "-n", "-j2", "--rerun-incomplete", check=True)
    planned = scheduled_jobs(dry.stdout + dry.stderr)
    assert {"identify", "gather_modal", "doe", "harmonic", "diagnose"} <= set(planned), planned


@pytest.mark.slow
def test_kill_9_of_a_job_and_of_snakemake_then_reproduce_rebuilds(clone, coarse_run):
    """kill -9 of a job mid-compute and of snakemake (the other job is orphaned): the lock refuses in
    one line, --unlock, then the README's command stops the orphan and rebuilds, byte for byte."""
    proc = start(clone, "--forcerun", "harmonic")  # both states' harmonic jobs (about 3 s of compute each)
    try:
        victim = wait_for(lambda: job_of(clone, "harmonic", "power_on"), proc, "harmonic[power_on] job")
        os.kill(int(victim["pid"]), signal.SIGKILL)
        os.kill(proc.pid, signal.SIGKILL)  # snakemake alone: its other job runs on, orphaned
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert not (clone / "results/harmonic/power_on/frf.csv").exists(), "snakemake removes a job's outputs first"
    rc, out = reproduce(clone)
    assert rc == 1 and lines_with(out, "holds a lock") and "snakemake --unlock" in out, out
    run_snakemake(clone, "--unlock", check=True)
    rc, out = reproduce(clone)
    assert_rebuilt(clone, coarse_run, rc, out)
    assert not group_alive(proc.pid)


@pytest.mark.slow
@pytest.mark.extended  # the default suite kills snakemake together with a job (the test above)
def test_kill_9_of_snakemake_alone_then_reproduce_rebuilds(clone, coarse_run):
    """kill -9 of snakemake while a job runs: the job may finish on its own (its output stays marked
    incomplete) or is stopped by the next run; either way the rebuild is complete and identical."""
    proc = start(clone, "--forcerun", "carriage_rigidity")
    try:
        wait_for(lambda: job_of(clone, "carriage_rigidity"), proc, "carriage_rigidity job")
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    run_snakemake(clone, "--unlock", check=True)
    rc, out = reproduce(clone)
    assert_rebuilt(clone, coarse_run, rc, out)


def kill_while_matrices_written(wd: Path, *args: str) -> Path:
    """Start snakemake with ``args``, SIGKILL its whole group while results/model/matrices.npz (the
    largest file) is being written; return the temporary file the writer left."""
    model = wd / "results" / "model"
    proc = start(wd, *args)
    try:
        tmp = wait_for(lambda: [p for p in model.glob(".matrices.npz.*.tmp") if p.stat().st_size > 0], proc,
                       "temporary matrices.npz being written")[0]
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert not (model / "matrices.npz").exists() and tmp.exists()
    deadline = time.monotonic() + 30
    while group_alive(proc.pid):  # SIGKILLed processes may take a moment to exit
        assert time.monotonic() < deadline, f"processes of the killed run alive: {group_alive(proc.pid)}"
        time.sleep(0.05)
    run_snakemake(wd, "--unlock", check=True)
    return tmp


STALE_MATRICES = "stale temporary file(s) of killed writers: results/model/.matrices.npz."


@pytest.mark.slow
def test_kill_9_while_the_largest_file_is_written_leaves_no_half_file_and_its_job_rebuilds_it(coarse_run, tmp_path):
    """kill -9 of a fresh run while results/model/matrices.npz is written: no half file; the README's
    command removes the temporary file (heal), and the mesh job writes the same bytes again.  The
    rest of the README's command is then a whole run from a folder without results, as ``coarse_run``
    is; with a complete earlier run around it, the extended test below rebuilds the whole chain."""
    wd = copy_workflow(tmp_path / "wf")
    mesh_outputs = ("results/model/matrices.npz", "results/model/summary.json", "results/model/mesh.vtu",
                    "results/model/measuring_points.csv")
    tmp = kill_while_matrices_written(wd, mesh_outputs[0])
    heal = subprocess.run([str(JOINTID), "results", "heal"], cwd=wd, capture_output=True, text=True,
                          env=workflow_env(), timeout=120)
    assert heal.returncode == 0 and len(lines_with(heal.stdout, STALE_MATRICES)) == 1, heal.stdout + heal.stderr
    assert not tmp.exists()
    run_snakemake(wd, "-j2", "--rerun-incomplete", *mesh_outputs, check=True)
    got, want = artifacts(wd), artifacts(coarse_run)
    assert {k: got.get(k) for k in mesh_outputs} == {k: want[k] for k in mesh_outputs}
    assert temporary_files(wd / "results") == [] and incomplete_markers(wd) == [] and jobs.running(wd) == []


@pytest.mark.slow
@pytest.mark.extended
def test_kill_9_while_the_largest_file_is_written_then_reproduce_rebuilds(clone, coarse_run):
    """kill -9 of the whole run while results/model/matrices.npz is written: no half file, the
    temporary file is removed by the next run, and every result is rebuilt (the whole chain)."""
    kill_while_matrices_written(clone, "--forcerun", "mesh")
    rc, out = reproduce(clone)
    assert lines_with(out, STALE_MATRICES), out
    # heal repaired something, so the kept subspace went with it: the diagnosis reruns from clean and its
    # files are byte-identical too
    assert lines_with(out, "kept diagnosis subspace(s)"), out
    assert_rebuilt(clone, coarse_run, rc, out)


@pytest.mark.slow
def test_truncated_npz_json_and_csv_results_are_removed_and_rebuilt(clone, coarse_run):
    damaged = ("results/harmonic/power_on/modes.npz", "results/identify/power_on/carriage_rigidity.json",
               "results/tables/table2_power_off.csv")
    for rel in damaged:
        cut_to_half(clone / rel)
    rc, out = reproduce(clone)
    for rel in damaged:
        assert len(lines_with(out, f"removed damaged {rel}: its SHA-256")) == 1, out
    assert_rebuilt(clone, coarse_run, rc, out)


@pytest.mark.slow
def test_a_rule_reading_a_truncated_npz_names_it_in_one_line(clone):
    """Without the heal (a targeted snakemake run), the job that reads the damaged file fails at once,
    naming it (the probe: all.npz cut to half, then its consumer rerun)."""
    cut_to_half(clone / "results/modal/all.npz")
    proc = run_snakemake(clone, "-j1", "--forcerun", "fit_surface", "results/surface/model.json")
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    hits = lines_with(out, "error in rule fit_surface: cannot read results/modal/all.npz: its SHA-256")
    assert len(hits) == 1 and "make reproduce" in hits[0], tail(out)
    assert "Traceback" not in out


@pytest.mark.slow
@pytest.mark.parametrize("code, words", [
    ("ENOSPC", "no space left on the device (it needs about "),
    # the writers' EACCES is in the default suite above (test_a_failed_write_is_one_line_...)
    pytest.param("EACCES", "permission denied (the temporary file is made in results/tables)",
                 marks=pytest.mark.extended)])
def test_a_full_disk_or_a_denied_write_is_one_line_then_reproduce_rebuilds(clone, coarse_run, code, words):
    (clone / "results/tables/table2_power_off.csv").unlink()
    rc, out = reproduce(clone, env={FAULT_ENV: f"{code}:*/table2_power_off.csv"})
    assert rc != 0
    hits = lines_with(out, "error in rule tables: cannot write results/tables/table2_power_off.csv: ")
    assert len(hits) == 1 and words in hits[0], tail(out)
    assert "Traceback" not in out
    assert not (clone / "results/tables/table2_power_off.csv").exists() and temporary_files(clone / "results") == []
    rc, out = reproduce(clone)
    assert_rebuilt(clone, coarse_run, rc, out)


# ------------------------------------------------------------------ provenance: git_dirty
def _git(cwd: Path, *args: str) -> None:
    subprocess.run(["git", "-c", "user.email=t@example.org", "-c", "user.name=t", *args], cwd=cwd, check=True,
                   capture_output=True)


def test_git_dirty_counts_the_config_as_loaded_and_a_revert_clears_it(tmp_path, monkeypatch):
    from jointid.reporting.provenance import CONFIG_ENV, git_state, pin_config_state

    original, edited = "mesh: {refine: 1}\nharmonic: {n_freq: 400}\n", "mesh: {refine: 2}\nharmonic: {n_freq: 400}\n"
    config, code = tmp_path / "config.yaml", tmp_path / "code.py"
    config.write_text(original)
    code.write_text("x = 1\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-qm", "init")
    monkeypatch.chdir(tmp_path)

    def dirty(sections):
        return git_state(tmp_path, sections=sections)[1]

    def new_run():  # a new snakemake: the config files are pinned as they are now
        monkeypatch.delenv(CONFIG_ENV, raising=False)
        pin_config_state(["config.yaml"])

    new_run()  # config.yaml edited during a run, then reverted: the run's values are the committed ones
    config.write_text(edited)
    assert dirty(["mesh"]) is False and dirty(None) is False
    config.write_text(original)
    assert dirty(["mesh"]) is False
    code.write_text("x = 2\n")  # code changed when an output is written: dirty; reverted: clean
    assert dirty(["mesh"]) is True
    code.write_text("x = 1\n")
    assert dirty(["mesh"]) is False
    config.write_text(edited)  # edited before a run: dirty in the sections that differ only
    new_run()
    assert dirty(["mesh"]) is True and dirty(["harmonic"]) is False and dirty(None) is True
    config.write_text(original)  # reverted: the next run (which reruns the rules of `mesh`) is clean
    new_run()
    assert dirty(["mesh"]) is False and dirty(None) is False


def test_a_config_file_outside_a_checkout_changes_nothing_the_commit_holds(tmp_path):
    """A workflow copied out of its checkout (the tests' runs, a user's own folder): its config is no
    part of a commit, so it cannot make the outputs dirty."""
    from jointid.reporting.provenance import config_changes

    (tmp_path / "config.yaml").write_text("mesh: {refine: 2}\n")
    assert config_changes([tmp_path / "config.yaml"])["changed_sections"] == []
