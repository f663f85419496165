"""Glue between Snakemake scripts and the package: logging, clean errors, config from params."""

from __future__ import annotations

import os
import signal
import sys
import traceback
from collections.abc import Iterable

from jointid.errors import JointidError
from jointid.progress import stamp

EXIT_TERMINATED = 128 + signal.SIGTERM
"""Exit status of a stage stopped by SIGTERM (as a shell reports a process killed by it)."""


class Terminated(SystemExit):
    """Raised by the SIGTERM handler of :func:`run_script` (a ``SystemExit``: not caught as an error)."""


def log(msg: str) -> None:
    """Print a stage's progress line at once, with the wall-clock time (the rule's log is a pipe,
    not a terminal)."""
    print(stamp(msg), flush=True)


def _on_sigterm(signum, frame):
    from jointid import io

    removed = io.remove_in_flight()
    print(f"terminated by signal {signum}; removed {len(removed)} unfinished output(s)",
          file=sys.stderr, flush=True)
    raise Terminated(EXIT_TERMINATED)


def install_sigterm_handler() -> None:
    """On SIGTERM remove the temporary files of writes in progress and exit with status 143.

    Snakemake (and cluster schedulers) stop jobs with SIGTERM; without the handler the process dies
    at once and leaves its ``.<name>.*.tmp`` files behind.  The previous result stays untouched
    either way (writes are atomic).
    """
    signal.signal(signal.SIGTERM, _on_sigterm)


def input_files(paths: Iterable[str]) -> list[str]:
    """The input files of a job, folders replaced by the files inside them (sorted, recursive)."""
    out = []
    for p in paths:
        p = str(p)
        if os.path.isdir(p):
            for root, dirs, files in os.walk(p):
                dirs.sort()
                out.extend(os.path.join(root, f) for f in sorted(files) if not f.startswith("."))
        else:
            out.append(p)
    return out


def write_sidecars(outputs: Iterable[str], cfg, inputs: Iterable[str]) -> list:
    """Provenance sidecar ``<output>.provenance.json`` of each output (see :mod:`jointid.reporting.provenance`)."""
    from jointid.reporting.provenance import write_provenance

    inputs = input_files(inputs)
    return [write_provenance(out, cfg, inputs=inputs) for out in outputs]


def run_script(smk, fn, provenance: bool | Iterable[str] = False) -> None:
    """Run ``fn(cfg, input, output)`` with stdout/stderr sent to the rule's log.

    ``cfg`` is ``smk.params.cfg`` (the config sections the rule depends on, passed through ``params:``
    so that a change reruns exactly the affected rules).  A :class:`JointidError` is printed as its
    problem lines (no traceback) and the script exits 1; Snakemake then removes the rule's outputs.
    SIGTERM removes the temporary files of unfinished writes and exits with status 143.

    With ``provenance`` (True: every output; or the names of outputs) each of those outputs gets a
    sidecar ``<output>.provenance.json`` once ``fn`` has succeeded: git commit, hash of ``cfg``,
    package versions, SHA-256 of the job's input files and of the output.
    """
    install_sigterm_handler()
    log = smk.log[0] if len(smk.log) else None
    fh = open(log, "w") if log else None
    if fh:
        sys.stdout = sys.stderr = _Tee(fh, sys.__stderr__)
    try:
        fn(smk.params.cfg, smk.input, smk.output)
        if provenance:
            outs = list(smk.output) if provenance is True else [getattr(smk.output, n) for n in provenance]
            write_sidecars(outs, smk.params.cfg, list(smk.input))
    except JointidError as exc:
        print(f"error in rule {smk.rule}:\n{exc}", file=sys.stderr)
        sys.exit(1)
    except Exception:
        traceback.print_exc()
        sys.exit(1)
    finally:
        if fh:
            fh.flush()


class _Tee:
    def __init__(self, *streams):
        self.streams = streams

    def write(self, s):
        for st in self.streams:
            st.write(s)

    def flush(self):
        for st in self.streams:
            st.flush()
