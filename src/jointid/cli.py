"""The ``jointid`` command: one entry point for the package's command lines.

``jointid <command> [arguments ...]`` runs ``python -m jointid.<command> [arguments ...]``::

    jointid config check config.yaml
    jointid diagnose --dataset data/rig --out results/diagnosis
    jointid checks --table1 results/tables
    jointid data ema hammer.uff --out data/hammer     (the same as `jointid ema ...`)

Only the chosen command's module is imported.  Exit status: the command's own (0 = fine), 1 for a
:class:`~jointid.errors.JointidError` the command did not report itself, 2 for no or an unknown
command.
"""

from __future__ import annotations

import importlib
import sys

from jointid.errors import JointidError

MODULES = {
    "diagnose": "jointid.diagnosis.__main__",
    "config": "jointid.config.__main__",
    "checks": "jointid.reporting.checks",
    "synth": "jointid.synthetic.generate",
    "uff": "jointid.data.uff",
    "data": "jointid.data.__main__",
    "ema": "jointid.ema.__main__",
    "export-mesh": "jointid.fe.meshexport",
    "results": "jointid.stages.recovery",
}
COMMANDS = {
    "diagnose": "diagnose which listed physical effect the model lacks (--dataset DIR --out DIR)",
    "config": "check a config file, print the key reference or a config hash (check|reference|hash)",
    "checks": "acceptance checks on the reproduced tables (CI gate; --table1, --tables2-3)",
    "synth": "write a synthetic dataset from a truth YAML file (--truth FILE --out DIR)",
    "uff": "import a Universal File (.unv/.uff) into a dataset folder",
    "data": "validate dataset folders (check FOLDER ...); modes from FRFs (ema FRF --out DIR, also `jointid ema`)",
    "ema": "modes from measured FRFs: EMA into a dataset folder (FRF.uff|frf.csv|DATASET --out DIR)",
    "export-mesh": "write the rig as a mesh file with named groups and its model: config (--out DIR)",
    "results": "heal: stop orphaned jobs, remove stale temporary files and damaged results before a run",
}


def usage() -> str:
    """The usage text: one line per command."""
    width = max(map(len, COMMANDS)) + 2
    lines = ["usage: jointid <command> [arguments ...]", "", "commands:"]
    lines += [f"  {name:<{width}}{text}" for name, text in COMMANDS.items()]
    lines += ["", "Run `jointid <command> --help` for a command's arguments."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv`` (default ``sys.argv[1:]``) to ``jointid.<command>.main``; returns the exit status.

    Parameters
    ----------
    argv : list of str, optional
        The command name followed by its arguments, which are passed on unchanged.

    Returns
    -------
    int
        The command's exit status; 0 for ``--help``, 2 for no or an unknown command.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    if args and args[0] in ("-V", "--version"):
        from jointid import __version__

        print(f"jointid {__version__}")
        return 0
    if args and args[0] in ("-h", "--help"):
        print(usage())
        return 0
    if not args or args[0] not in COMMANDS:
        what = f"unknown command {args[0]!r}" if args else "no command given"
        print(f"jointid: {what}; choose one of: {', '.join(COMMANDS)}\n\n{usage()}", file=sys.stderr)
        return 2
    if args[:2] == ["data", "ema"]:  # `jointid data ema ...` is the EMA's command line (jointid.ema)
        args = args[1:]
    module = importlib.import_module(MODULES[args[0]])
    try:
        return module.main(args[1:])
    except JointidError as exc:  # a command that lets one escape still ends with a message, not a traceback
        print(str(exc), file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
