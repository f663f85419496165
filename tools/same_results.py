"""Are two runs' results the same?  ``python tools/same_results.py RUN_A RUN_B``

Compares, byte for byte, the files a user reads as results: every ``results/tables/*.csv``,
``results/identify/*/params.json``, ``results/diagnosis/*/ranking.csv`` (plus ladder.csv and
verify.csv) and the hypotheses' ``ranking.csv`` and ``fit.json``, in two run folders (each the folder holding ``results/``).  A JSON file that differs only
in a provenance field naming the code (``git_commit``, ``git_dirty``, ``jointid_version``, ``code``) counts
as the same, and is reported as such.  Prints one line per file and exits 1 if any differs.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

PATTERNS = ("results/tables/*.csv", "results/identify/*/params.json", "results/identify/*/verify.csv",
            "results/diagnosis/*/ranking.csv", "results/diagnosis/*/ladder.csv",
            "results/hypotheses/ranking.csv", "results/hypotheses/*/fit.json")
CODE_FIELDS = {"git_commit", "git_dirty", "git_describe", "jointid_version", "code", "commit", "dirty"}


def _strip(obj):
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if k not in CODE_FIELDS}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def compare(a: Path, b: Path) -> int:
    names = sorted({str(p.relative_to(run)) for run in (a, b) for pat in PATTERNS for p in run.glob(pat)})
    bad = 0
    for name in names:
        fa, fb = a / name, b / name
        if not (fa.exists() and fb.exists()):
            print(f"MISSING  {name} ({'only in ' + str(a if fa.exists() else b)})")
            bad += 1
            continue
        ta, tb = fa.read_bytes(), fb.read_bytes()
        if ta == tb:
            print(f"same     {name}")
        elif name.endswith(".json") and _strip(json.loads(ta)) == _strip(json.loads(tb)):
            print(f"same     {name} (apart from the code's provenance)")
        else:
            print(f"DIFFERS  {name}")
            bad += 1
    print(f"{len(names) - bad} of {len(names)} files the same")
    return 1 if bad or not names else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(compare(Path(sys.argv[1]), Path(sys.argv[2])))
