"""Benchmark j: rebuild the rows of a run that was stopped before it wrote its CSV (a version before the
rows were saved after every case), from its per-case tables (benchmarks/out/coverage_runs/<run>/<case>/)
and its progress log (explained_by, times).  One-off; used for the 2026-11-28 run with the defaults.

    python -m benchmarks.j_recover LOG RUN_DIR_NAME "RUN LABEL" OUT.csv
"""
import json, re, sys, time
from pathlib import Path
from types import SimpleNamespace
import numpy as np, pandas as pd
from benchmarks import bench_j_coverage as m

log_path, slug, label, out_csv = sys.argv[1:5]
pat = re.compile(r"^\[j\]\s+\d+/\d+ (\S+) .*? modes: (.+?) +(found|MISSED|CLAIMED|none claimed) +effect CI .*?  ([\d.]+) s \(synth ([\d.]+) s\)")
seen = {}
for line in Path(log_path).read_text().splitlines():
    mm = pat.match(line)
    if mm:
        seen[mm.group(1)] = (mm.group(2).strip(), float(mm.group(4)), float(mm.group(5)))
cases = {c["case"]: c for c in m.design()}

class ME:
    def record(self): return {}
    def sentence(self): return ""

rows = []
for cid, (eb, t, ts) in seen.items():
    c = cases[cid]
    d = m.OUT / "coverage_runs" / slug / cid
    if eb.startswith("ERROR") or not (d / "ranking.csv").exists():
        row = {"case": cid, "kind": c["kind"], "truth": "+".join(c["effects"]) or "none", "noise": c["noise"],
               "shapes": bool(c["shapes"]), "max_modes": c["max_modes"], "seed": c["seed"], "explained_by": eb,
               "verdict": "(the diagnosis raised; see the report)"}
        for i, name in enumerate(c["effects"], 1):
            row.update({f"eff{i}": name, f"eff{i}_in": False})
        for s in ("kn", "kl"):
            row.update({f"{s}_rep_in": False, f"{s}_true_in": False})
        row.update(m.judge(row["truth"], eb, None, None))
    else:
        comb = d / "combinations.csv"
        try:
            cb = pd.read_csv(comb)
        except Exception:
            cb = pd.DataFrame()
        res = SimpleNamespace(ranking=pd.read_csv(d / "ranking.csv"), parameters=pd.read_csv(d / "parameters.csv"),
                              combinations=cb, explained_by=eb, verdict=(d / "verdict.txt").read_text().strip(),
                              model_error=ME(), identifiable={}, absorbed=[], next_measurements=pd.DataFrame(),
                              notes=[], timing_s=0.0)
        row = m.score(c, res)
    row.update({"run": label, "rig": "coarse", "options": "{}", "synth_s": ts, "time_s": t})
    rows.append(row)
df = pd.DataFrame(rows)
print(len(df), "cases recovered")
df.to_csv(out_csv, index=False)
