"""Job tickets: which workflow jobs are running in this folder, so that orphans can be found.

When ``snakemake`` itself is killed (SIGKILL, a closed terminal, power loss of the login node), its
running jobs go on: nothing tells them to stop, and one may write its output minutes later, into the
next run.  Each job of :func:`jointid.stages.runner.run_script` therefore holds a ticket
``.snakemake/jointid_jobs/<host>_<pid>.json`` (rule, outputs, process start time) while it runs and
removes it when it ends.

``jointid results heal`` (run by ``make reproduce`` before Snakemake, only when no Snakemake run holds
the folder's lock) stops the orphans: a ticket of this host whose process is alive belongs to a job
whose ``snakemake`` is gone.  The choice is to stop them, not to wait or refuse: Snakemake marked
their outputs incomplete when they started, so ``--rerun-incomplete`` redoes them anyway; waiting
would only let a stale writer race the new run, and refusing would ask the user to do by hand what
is safe to do here.  They get SIGTERM first (their handler removes their temporary files), SIGKILL
after :data:`STOP_TIMEOUT_S`.  A ticket names the process start time, so a recycled process id is
never signalled.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import time
from pathlib import Path

JOBS_DIR = Path(".snakemake") / "jointid_jobs"
STOP_TIMEOUT_S = 20.0


def _start_ticks(pid: int) -> str | None:
    """The start time of process ``pid`` in clock ticks since boot (``/proc``), or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rfind(")") + 2:].split()
    if fields[0] == "Z":  # a zombie has ended
        return None
    return fields[19]  # field 22 of stat(5), counted after the command name


def _host() -> str:
    return socket.gethostname()


def register(rule: str, outputs, workdir: str | os.PathLike = ".") -> Path | None:
    """Write this process's ticket; returns its path (None where the folder is not writable)."""
    folder = Path(workdir) / JOBS_DIR
    ticket = folder / f"{_host()}_{os.getpid()}.json"
    rec = {"pid": os.getpid(), "host": _host(), "start_ticks": _start_ticks(os.getpid()), "rule": str(rule),
           "outputs": [str(o) for o in outputs], "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    try:
        folder.mkdir(parents=True, exist_ok=True)
        ticket.write_text(json.dumps(rec))
    except OSError:
        return None
    return ticket


def unregister(ticket: Path | None) -> None:
    if ticket is not None:
        try:
            ticket.unlink()
        except OSError:
            pass


def _alive(rec: dict) -> bool:
    return rec.get("host") == _host() and rec.get("start_ticks") is not None \
        and _start_ticks(int(rec["pid"])) == rec["start_ticks"]


def running(workdir: str | os.PathLike = ".") -> list[dict]:
    """The tickets of jobs still running on this host (stale tickets are removed)."""
    folder = Path(workdir) / JOBS_DIR
    out = []
    for ticket in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        try:
            rec = json.loads(ticket.read_text())
        except (OSError, ValueError):
            rec = {}
        if _alive(rec):
            out.append({**rec, "ticket": str(ticket)})
        elif rec.get("host", _host()) == _host():
            unregister(ticket)
    return out


def stop(rec: dict, timeout_s: float = STOP_TIMEOUT_S) -> str:
    """Stop the job of ticket ``rec``: SIGTERM, then SIGKILL after ``timeout_s``; returns how it ended."""
    pid = int(rec["pid"])
    how = "stopped (SIGTERM)"
    try:
        os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + timeout_s
        while _alive(rec) and time.monotonic() < deadline:
            time.sleep(0.1)
        if _alive(rec):
            os.kill(pid, signal.SIGKILL)
            how = "killed (SIGKILL: it did not stop on SIGTERM)"
            while _alive(rec):
                time.sleep(0.05)
    except ProcessLookupError:
        how = "already ended"
    unregister(Path(rec["ticket"]))
    return how
