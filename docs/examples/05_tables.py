"""Tables 2-3 of the paper through the API: the whole method, as the workflow runs it.

Run from the repository root:  python docs/examples/05_tables.py [folder]

`study.run_method()` runs the DOE, the response surfaces (here with the zoomed second DOE of the coarse
configuration), the multistart and FE polish of each state, the FE verification and the tables, through
the workflow's own stage functions (`jointid.stages.method`).  Its numbers are those of
`snakemake -j2 --configfile config.yaml tests/coarse_config.yaml` (results/tables/), to the last digit
with single-threaded BLAS, as the workflow's jobs run.  About a minute on the coarse mesh.  With a
folder, it writes the workflow's files there (identify/<state>/params.json, verify.csv, tables/<state>.csv).
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # as the workflow's jobs: before numpy is loaded

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from jointid import Study  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else None
os.chdir(ROOT)  # the configuration's dataset folders (data/paper) are relative to the repository root
study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])

t0 = time.perf_counter()
result = study.run_method()
print(f"the method on {len(result.tables)} states in {time.perf_counter() - t0:.0f} s")

for number, (state, table) in enumerate(result.tables.items(), start=2):
    print(f"\nTable {number} ({state}): measured, simulated at the identified joints, the paper's simulation")
    print(table.to_string(index=False, float_format="%.10g"))
    print(f"{state}: max |error| {result.max_abs_error_pct(state):.2f} %")
    for name, value in result.theta(state).items():
        print(f"{state} {name} = {value:.10g} N/m^3")

if OUT is not None:
    for path in result.write(OUT):
        print("wrote", path)
