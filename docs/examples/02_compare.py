"""Compare the model with a modal test: the paper's measured frequencies, then a UFF file with shapes.

Run from the repository root:  python docs/examples/02_compare.py

A dataset is a folder (modes.csv [+ shapes.csv] + conditions.yaml, docs/measurement-format.md) or a
Universal File (.uff/.unv) from the test software; `study.compare` pairs the measured modes with the
model's (by MAC where shapes were measured, else by frequency) and gives the error of each.
"""

import tempfile
from pathlib import Path

import numpy as np

from jointid import Study
from jointid.correlate.pairing import error_summary
from jointid.data.uff_export import write_modes_uff

ROOT = Path(__file__).resolve().parents[2]
study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])
COLUMNS = ["state", "mode", "freq_meas_Hz", "freq_model_Hz", "error_pct", "mac", "status", "description"]

# 1. The paper's test (frequencies only, two states) against the model at the default joint stiffness.
paper = study.compare(ROOT / "data" / "paper")
print("paper's data vs the model at the default joint stiffness (before any identification):")
print(paper[COLUMNS].round(2).to_string(index=False))
print(error_summary(paper).round(2).to_string(index=False))

# 2. A test with mode shapes, as a UFF file.  Here the "test" is the model itself with a stiffer feed
#    joint and 5 % noise on the shapes, written as a test-lab export would be (datasets 164, 15, 55); a
#    real file is read the same way.
truth = {"k_feed_N_per_m3": 2.5e10}
test = study.modes(truth, n=8)
noise = 0.05 * np.random.default_rng(1).normal(size=test.shapes.shape) * test.shapes.std(axis=0)
with tempfile.TemporaryDirectory() as tmp:
    uff = Path(tmp) / "hammer_test.uff"
    write_modes_uff(uff, study.points(), test.labels, test.freqs_Hz, test.shapes + noise, title="hammer test")
    table = study.compare(uff)  # imported as state power_off, nodes mapped to the points by coordinates
print(f"\nUFF test (k_feed {truth['k_feed_N_per_m3']:.2g} N/m^3) vs the model at the default k_feed "
      f"{study.theta()['k_feed_N_per_m3']:.3g} N/m^3:")
print(table[COLUMNS].round(3).to_string(index=False))
paired = table[table.status == "paired"]
worst = paired.loc[paired.error_pct.abs().idxmax()]
print(f"paired by MAC: {len(paired)} modes, MAC min {paired.mac.min():.3f}; "
      f"largest error {abs(worst.error_pct):.1f} % ({worst.description})")
