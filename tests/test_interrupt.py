"""Interruption: a killed writer or a killed ``snakemake -j2`` never leaves a corrupt result, and a
rerun with ``--rerun-incomplete`` finishes (its results equal an uninterrupted run's: see
``test_determinism``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import assert_arrays_equal, incomplete_markers, npz_arrays, temporary_files
from jointid import io

WRITER = textwrap.dedent("""
    import sys, time
    from jointid.io import atomic_path
    with atomic_path(sys.argv[1]) as tmp:
        tmp.write_bytes(b"half of a new result")
        print(tmp, flush=True)
        time.sleep(120)
""")


def _killed_writer(target: Path, sig: int) -> Path:
    """Run a writer that stops inside ``atomic_path``; kill it with ``sig``; return its temp path."""
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target)], stdout=subprocess.PIPE,
                            text=True)
    try:
        tmp = Path(proc.stdout.readline().strip())
        assert tmp.parent == target.parent and tmp.is_file()
        proc.send_signal(sig)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
    return tmp


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killed_writer_keeps_previous_result(tmp_path, sig):
    target = tmp_path / "params.json"
    io.write_json(target, {"value": 1.0})
    before = target.read_bytes()
    _killed_writer(target, sig)
    assert target.read_bytes() == before, "the old result must survive an interrupted rewrite"


def test_killed_writer_leaves_no_result_where_there_was_none(tmp_path):
    target = tmp_path / "modal" / "d003.npz"
    _killed_writer(target, signal.SIGKILL)
    assert not target.exists(), "an interrupted first write must not create the output"


def test_next_write_removes_stale_temp_file_of_a_killed_writer(tmp_path):
    target = tmp_path / "d003.npz"
    stale = _killed_writer(target, signal.SIGKILL)
    assert stale.is_file(), "SIGKILL leaves the temporary file (nothing can run in the writer)"
    io.write_npz(target, freqs_Hz=np.arange(3.0))
    assert np.array_equal(npz_arrays(target)["freqs_Hz"], np.arange(3.0))
    assert temporary_files(tmp_path) == []


def test_results_get_the_permissions_of_a_new_file_not_the_private_temporary_ones(tmp_path):
    # the temporary file is created private (0600); a result shared with a group or read by batch
    # jobs under another account must end up as any new file would (umask)
    old = os.umask(0o027)
    try:
        io._UMASK = 0o027
        io.write_text(tmp_path / "a.txt", "x")
        assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)
        io._UMASK = old


def _fake_temporary(target: Path, middle: str, age_s: float = 0.0) -> Path:
    p = target.with_name(f".{target.name}.{middle}.tmp")
    p.write_bytes(b"partial")
    if age_s:
        t = time.time() - age_s
        os.utime(p, (t, t))
    return p


def test_stale_cleanup_keeps_live_writers_and_other_targets(tmp_path):
    target = tmp_path / "table2_power_off.csv"
    host = io._host_tag()
    live = _fake_temporary(target, f"p{os.getppid()}h{host}_abc123")  # a running process (pytest's parent)
    dead = _fake_temporary(target, f"p{2**22 + 12345}h{host}_abc123")  # above pid_max: no such process
    other_host_new = _fake_temporary(target, "p1h0123abcd_abc123")
    other_host_old = _fake_temporary(target, "p1h0123abcd_def456", age_s=2 * io.STALE_AFTER_S)
    legacy_old = _fake_temporary(target, "k2j4_x9q", age_s=2 * io.STALE_AFTER_S)
    sidecar = target.with_name(target.name + ".provenance.json")
    other_target = _fake_temporary(sidecar, f"p{2**22 + 12345}h{host}_abc123")  # not target's
    io.write_text(target, "order\n1\n")
    assert target.read_text() == "order\n1\n"
    assert live.exists() and other_host_new.exists() and other_target.exists()
    assert not dead.exists() and not other_host_old.exists() and not legacy_old.exists()


# The stage sleeps in short steps, as a job computes.  One long sleep would not do: numpy's BLAS starts a
# thread at import, the kernel may deliver the SIGTERM to it, and the main thread, whose sleep is then not
# interrupted, runs Python's handler only when it wakes (seen once in eight runs on a loaded machine).
SIGTERM_STAGE = textwrap.dedent("""
    import sys, time
    from types import SimpleNamespace
    from jointid.io import atomic_path
    from jointid.stages.runner import run_script

    target, log = sys.argv[1], sys.argv[2]

    def stage(cfg, inp, out):
        with atomic_path(out[0]) as tmp:
            tmp.write_bytes(b"half of a new result")
            print(tmp, file=sys.__stdout__, flush=True)
            while True:  # a working job: Python runs the handler between two bytecodes
                time.sleep(0.1)

    smk = SimpleNamespace(log=[log], params=SimpleNamespace(cfg={}), input=[], output=[target],
                          rule="probe")
    run_script(smk, stage)
""")


def test_sigterm_to_a_stage_removes_its_temporary_files_and_exits_nonzero(tmp_path):
    target, log = tmp_path / "verify.csv", tmp_path / "probe.log"
    io.write_text(target, "old result\n")
    proc = subprocess.Popen([sys.executable, "-c", SIGTERM_STAGE, str(target), str(log)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        tmp = Path(proc.stdout.readline().strip())
        assert tmp.parent == tmp_path and tmp.is_file()
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
    assert rc == 128 + signal.SIGTERM
    assert not tmp.exists() and temporary_files(tmp_path) == []
    assert target.read_text() == "old result\n", "the previous result survives"
    assert "terminated by signal 15; removed 1 unfinished output(s)" in log.read_text()


@pytest.mark.slow
def test_kill_during_doe_fanout_leaves_complete_points_and_rerun_incomplete_finishes(coarse_run, resumed_run):
    """The kill and the resume; that the resumed run's results equal the uninterrupted run's, file
    for file, is checked by ``test_determinism.test_a_second_run_killed_and_resumed_is_byte_identical``."""
    ref, run = coarse_run, resumed_run
    assert not run.survivors, f"jobs of the killed run survived: {run.survivors}"
    assert 1 <= len(run.done_at_kill) < run.n_points, \
        f"killed after {len(run.done_at_kill)} of {run.n_points} DOE points"
    assert run.tables_at_kill == [], "tables written before the DOE had finished"
    for name, arrays in run.done_at_kill.items():  # whatever exists is complete and correct (atomic writes)
        assert_arrays_equal(arrays, npz_arrays(ref / "results" / "modal" / "points" / name), name)
    assert temporary_files(run.workdir / "results") == [], "temporary files left after the rerun"
    assert incomplete_markers(run.workdir) == [], "Snakemake still marks outputs as incomplete"
