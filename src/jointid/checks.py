"""Acceptance checks on the reproduced tables (used by CI): ``python -m jointid.checks``.

Fails (exit 1, one line per problem) when a table is missing, lacks a column, or its largest
|relative error| exceeds the bound (by default the paper's own: 8.1 % power-off, 8.2 % power-on).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

COLUMNS = ["order", "experimental_Hz", "simulation_Hz", "relative_error_pct", "paper_simulation_Hz",
           "paper_relative_error_pct"]
TABLES = {"table2_power_off.csv": 8.1, "table3_power_on.csv": 8.2}


def check_frequency_tables(folder: str | Path, bounds: dict[str, float] = TABLES) -> list[str]:
    problems = []
    for name, bound in bounds.items():
        path = Path(folder) / name
        if not path.exists():
            problems.append(f"{path}: missing — run snakemake -j2")
            continue
        df = pd.read_csv(path)
        missing = [c for c in COLUMNS if c not in df.columns]
        if missing:
            problems.append(f"{path}: missing columns {missing}")
            continue
        worst = df["relative_error_pct"].abs().max()
        if not worst <= bound:
            problems.append(f"{path}: max |relative error| {worst:.2f} % exceeds the required {bound} %")
        else:
            print(f"{path}: max |relative error| {worst:.2f} % (required <= {bound} %)")
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("folder", nargs="?", default="results/tables")
    args = ap.parse_args(argv)
    problems = check_frequency_tables(args.folder)
    try:
        from .report import check_table1  # provided with the harmonic/report stage
    except ImportError:
        check_table1 = None
    if check_table1 is not None and (Path(args.folder) / "table1_dynamic_stiffness.csv").exists():
        problems += check_table1(Path(args.folder) / "table1_dynamic_stiffness.csv")
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
