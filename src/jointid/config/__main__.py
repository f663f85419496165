"""Command line of the configuration layer (also ``jointid config ...``)::

    python -m jointid.config check [config.yaml] [--set key=value ...]
    python -m jointid.config reference [--output docs/config-reference.md]
    python -m jointid.config hash [config.yaml] [key ...]

``check`` validates a file (with its dataset folders, relative to the working directory),
``reference`` prints the Markdown key reference, ``hash`` prints :func:`~jointid.config.config_hash`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jointid.config.hashing import config_hash
from jointid.config.load import load_config
from jointid.config.reference import config_reference_markdown
from jointid.config.schema import load_schema
from jointid.errors import ConfigError

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Command line: ``check``, ``reference`` and ``hash``; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m jointid.config", description="jointid configuration tools")
    sub = parser.add_subparsers(dest="command", required=True)
    p_check = sub.add_parser("check", help="validate a config file")
    p_check.add_argument("config", nargs="?", default="config.yaml")
    p_check.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                         help="override a key (dotted), value read as YAML; repeatable")
    p_ref = sub.add_parser("reference", help="print the Markdown key reference")
    p_ref.add_argument("--output", help="write to this file instead of stdout")
    p_hash = sub.add_parser("hash", help="print the config hash (of some sections)")
    p_hash.add_argument("config", nargs="?", default="config.yaml")
    p_hash.add_argument("keys", nargs="*")
    args = parser.parse_args(argv)
    try:
        if args.command == "check":
            load_config(args.config, overrides=args.overrides or None, check_datasets=True)
            print(f"{args.config}: OK")
        elif args.command == "reference":
            text = config_reference_markdown(load_schema())
            if args.output:
                Path(args.output).write_text(text, encoding="utf-8")
            else:
                sys.stdout.write(text)
        elif args.command == "hash":
            print(config_hash(load_config(args.config), args.keys or None))
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
