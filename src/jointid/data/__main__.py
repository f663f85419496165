"""Command line of the measured data: ``python -m jointid.data check FOLDER [FOLDER ...]``.

``check`` validates dataset folders (docs/measurement-format.md) the way every stage reading them
does, without running anything: every problem on one line (file, row, column, what is wrong, how to
fix it), exit status 1 if there is any.  With ``--points results/model/measuring_points.csv`` the
point names of shapes.csv, frf.csv and conditions.yaml are checked against the model's measuring
points too.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 valid, 1 problems, 2 usage)."""
    ap = argparse.ArgumentParser(prog="jointid data", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    chk = sub.add_parser("check", help="validate dataset folders; one line per problem")
    chk.add_argument("folders", nargs="+", help="dataset folders (modes.csv, conditions.yaml, ...)")
    chk.add_argument("--points", help="measuring_points.csv of the model (checks point names too)")
    chk.add_argument("--states", nargs="*", help="states every folder must hold")
    args = ap.parse_args(argv)
    import pandas as pd  # noqa: PLC0415  (heavy: after the arguments parse)

    from jointid.data.dataset import read_dataset, validate_dataset  # noqa: PLC0415

    points = None
    if args.points:
        if not Path(args.points).is_file():
            print(f"{args.points}: measuring-points file not found — it is written by the mesh rule "
                  "(snakemake -j2 results/model/measuring_points.csv)", file=sys.stderr)
            return 1
        points = pd.read_csv(args.points)
    status = 0
    for folder in args.folders:
        problems = validate_dataset(folder, measuring_points=points, expected_states=args.states)
        if problems:
            status = 1
            print("\n".join(problems), file=sys.stderr)
            continue
        ds = read_dataset(folder, measuring_points=points, expected_states=args.states)
        counts = ", ".join(f"{s}: {len(ds.freqs(s))} modes" for s in ds.states)
        extra = [n for n, v in (("shapes", ds.shapes), ("FRF", ds.frf)) if v is not None]
        print(f"{folder}: valid ({counts}{'; with ' + ' and '.join(extra) if extra else ''})")
    return status


if __name__ == "__main__":
    sys.exit(main())
