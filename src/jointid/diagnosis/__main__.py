"""Command line of the diagnosis: which listed physical effect does the model lack?

``python -m jointid.diagnosis --dataset DIR --out DIR [--config config.yaml ...] [--states ...]
[--effects YAML] [--matrices FILE] [--history CSV]`` (also ``jointid diagnose ...``); see
docs/effects.md.  Mistakes in the arguments are reported before any computation.
"""

from __future__ import annotations

import argparse
import os
import sys

import yaml

from jointid.config import load_config
from jointid.errors import ConfigError, JointidError
from jointid.config.typed_diagnosis import DiagnoseJob
from jointid.fe.model import build_model
from jointid.stages.diagnosis import run_diagnosis
from jointid.yamlio import read_merged

PROG = "python -m jointid.diagnosis"


def check_outputs(out_dir: str, history: str | None) -> None:
    """Fail before any computation when the outputs cannot be written."""
    problems = []
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        problems.append(f"--out {out_dir}: is a file, not a folder — name a folder for the outputs")
    if history is not None and os.path.isdir(history):
        problems.append(f"--history {history}: is a folder — name a CSV file to append the run's row to")
    for path in filter(None, (out_dir, history)):
        probe = os.path.abspath(path)
        while not os.path.exists(probe):  # the nearest existing folder is where it gets created
            probe = os.path.dirname(probe)
        if not os.access(probe, os.W_OK):
            problems.append(f"{path}: {probe} is not writable")
    if problems:
        raise ConfigError(problems)


def parser() -> argparse.ArgumentParser:
    """The argument parser of the command line."""
    ap = argparse.ArgumentParser(prog=PROG, description="Diagnose which listed physical effect the model lacks.")
    ap.add_argument("--dataset", required=True, help="dataset folder (measurement format)")
    ap.add_argument("--out", required=True, help="output folder (ranking.csv, ladder.csv, index.html ...)")
    ap.add_argument("--config", nargs="*", default=["config.yaml"], help="config files merged in order")
    ap.add_argument("--states", nargs="*", default=None, help="states to use (default all of the dataset)")
    ap.add_argument("--effects", default=None,
                    help="YAML mapping of enabled effects, e.g. '{em_preload: {beta: 0.2}}' (overrides config)")
    ap.add_argument("--matrices", default=None, help="cached model matrices (default: build from the config)")
    ap.add_argument("--history", default=None, help="CSV to append a run row to")
    return ap


def command_config(args: argparse.Namespace) -> dict:
    """The validated configuration of the command line (config files, ``--effects``, ``--dataset``)."""
    check_outputs(args.out, args.history)
    for path in args.config:
        if not os.path.isfile(path):
            raise ConfigError(f"--config {path}: no such file")
    if args.matrices is not None and not os.path.isfile(args.matrices):
        raise ConfigError(f"--matrices {args.matrices}: no such file — the mesh rule writes "
                          "results/model/matrices.npz; or leave --matrices out to build the model")
    raw = read_merged(args.config)
    if args.effects is not None:
        try:
            raw["effects"] = yaml.safe_load(args.effects) or {}
        except yaml.YAMLError as exc:
            raise ConfigError(f"--effects: not valid YAML ({str(exc).splitlines()[0]}) — write a mapping "
                              "such as '{em_preload: {beta: 0.2}}'") from None
    cfg = load_config(raw)
    cfg["dataset"] = {"path": args.dataset, "states": args.states}
    return cfg


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); returns the exit status (1 on a
    :class:`~jointid.errors.JointidError`, reported on stderr)."""
    args = parser().parse_args(argv)
    try:
        job = DiagnoseJob.from_config(command_config(args))  # the configuration typed once
        model = build_model(job.settings.model) if args.matrices is None else None
        name = args.dataset.rstrip("/").split("/")[-1]
        run_diagnosis(job, name, args.dataset, args.matrices, args.out, history_csv=args.history, model=model,
                      subspace=os.path.join(args.out, "subspace.npz"))
    except JointidError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
