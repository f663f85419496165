"""Glue between Snakemake scripts and the package: logging, clean errors, config from params."""

from __future__ import annotations

import sys
import traceback

from .errors import JointidError


def run_script(smk, fn) -> None:
    """Run ``fn(cfg, input, output)`` with stdout/stderr sent to the rule's log.

    ``cfg`` is ``smk.params.cfg`` (the config sections the rule depends on, passed through ``params:``
    so that a change reruns exactly the affected rules).  A :class:`JointidError` is printed as its
    problem lines (no traceback) and the script exits 1; Snakemake then removes the rule's outputs.
    """
    log = smk.log[0] if len(smk.log) else None
    fh = open(log, "w") if log else None
    if fh:
        sys.stdout = sys.stderr = _Tee(fh, sys.__stderr__)
    try:
        fn(smk.params.cfg, smk.input, smk.output)
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
