"""Glue between Snakemake scripts and the package: logging, clean errors, config from params.

Before a stage reads anything, every input file that has a provenance sidecar is checked against the
SHA-256 the sidecar recorded (:func:`check_inputs`): a damaged result is named in one line, with the
fix, instead of failing somewhere inside a reader.  The hashes serve the outputs' sidecars too.
"""

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


def check_inputs(inputs: Iterable[str]) -> dict[str, str]:
    """SHA-256 of every input file; raises :class:`jointid.io_errors.ResultReadError` (one line per
    damaged file) where an input does not match its provenance sidecar (a file cut short or changed
    since it was written).  Returns {path: sha256}."""
    from jointid.io_errors import read_error
    from jointid.reporting.provenance import check_sidecar, sha256_file

    hashes, problems = {}, []
    for path in input_files(inputs):
        if not os.path.isfile(path):
            continue
        hashes[path] = sha256_file(path)
        why = check_sidecar(path, hashes[path])
        if why:
            problems.append(str(read_error(path, why, checked=True)))
    if problems:
        from jointid.io_errors import ResultReadError

        raise ResultReadError(problems)
    return hashes


def write_sidecars(outputs: Iterable[str], stamp, inputs: Iterable[str], input_hashes=None) -> list:
    """Provenance sidecar ``<output>.provenance.json`` of each output (see :mod:`jointid.reporting.provenance`):
    one record for the job (git state, input hashes, ``stamp``: the :class:`jointid.config.ConfigStamp` of
    the rule's config), each output's own SHA-256 added."""
    from jointid.reporting.provenance import provenance, write_provenance

    inputs = input_files(inputs)
    record = provenance(stamp, inputs=inputs, input_hashes=input_hashes)
    return [write_provenance(out, stamp, record=record) for out in outputs]


def _one_line(exc: BaseException, limit: int = 200) -> str:
    text = " ".join(str(exc).split()) or "(no message)"
    return f"{type(exc).__name__}: {text[:limit]}{'...' if len(text) > limit else ''}"


def run_script(smk, fn, provenance: bool | Iterable[str] = True) -> None:
    """Run ``fn(cfg, input, output)`` with stdout/stderr sent to the rule's log.

    ``cfg`` is ``smk.params.cfg`` (the config sections the rule depends on, passed through ``params:``
    so that a change reruns exactly the affected rules); ``fn``, the rule script's adapter, turns it into its
    stage's typed options once (:mod:`jointid.config.options`): the stages never see the dict.  The inputs are checked against their
    provenance sidecars first (:func:`check_inputs`).  A :class:`JointidError` is printed as its
    problem lines (no traceback) and the script exits 1; Snakemake then removes the rule's outputs.
    Any other exception prints one line (what failed, in which rule, where the traceback is) and
    writes the traceback to the rule's log only.  SIGTERM removes the temporary files of unfinished
    writes and exits with status 143.  While it runs, the job holds a ticket
    (:mod:`jointid.stages.jobs`) by which a later run finds it if Snakemake was killed.

    With ``provenance`` (True, the default: every output; or the names of outputs) each of those
    outputs gets a sidecar ``<output>.provenance.json`` once ``fn`` has succeeded: git commit, hash
    of ``cfg``, package versions, SHA-256 of the job's input files and of the output.  A job that
    succeeded then ends its process at once (:func:`_leave`): ``run_script`` is a rule script's last call.
    """
    from jointid.stages import jobs

    install_sigterm_handler()
    log = smk.log[0] if len(smk.log) else None
    fh = open(log, "w") if log else None
    if fh:
        sys.stdout = sys.stderr = _Tee(fh, sys.__stderr__)
    ticket = jobs.register(smk.rule, list(smk.output))
    try:
        hashes = check_inputs(list(smk.input))
        fn(smk.params.cfg, smk.input, smk.output)
        if provenance:
            outs = list(smk.output) if provenance is True else [getattr(smk.output, n) for n in provenance]
            from jointid.config.hashing import ConfigStamp

            write_sidecars(outs, ConfigStamp.of(smk.params.cfg), list(smk.input), hashes)
    except JointidError as exc:
        if len(exc.problems) == 1:
            print(f"error in rule {smk.rule}: {exc.problems[0]}", file=sys.stderr)
        else:
            print(f"error in rule {smk.rule}:\n{exc}", file=sys.stderr)
        sys.exit(1)
    except Exception as exc:
        if fh:
            traceback.print_exc(file=fh)
            print(f"error in rule {smk.rule}: unexpected {_one_line(exc)}; the full traceback is in {log}",
                  file=sys.stderr)
        else:
            traceback.print_exc()
        sys.exit(1)
    finally:
        jobs.unregister(ticket)
        if fh:
            fh.flush()
    _leave()


def _leave() -> None:
    """End a job's process once its outputs and sidecars are written: the streams flushed, then
    ``os._exit(0)``.  Python's own teardown (every object of a job that held 1-2 GB freed one by one) is
    skipped, the system frees the memory at once: about 0.5 s of every diagnosis rerun (the loop of
    docs/effects.md) and of every job of the workflow.  Nothing is left to do at exit: the jobs' temporary
    folders and worker processes are closed by the code that made them."""
    for stream in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed stream: nothing to flush
            pass
    os._exit(0)


class _Tee:
    def __init__(self, *streams):
        self.streams = streams

    def write(self, s):
        for st in self.streams:
            st.write(s)

    def flush(self):
        for st in self.streams:
            st.flush()
