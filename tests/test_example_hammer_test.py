"""The hammer-test example (examples/hammer_test): FE FRFs with known joints -> EMA -> dataset -> the model.

Runs the example as a user would and checks what it claims: the dataset passes the check against the
model's measuring points, every paired mode holds the model at the true joints within 3 of its own sigma,
the identified normal and lateral stiffness hold the truth in their 95 % intervals; the joint damping of
power_off (hysteretic law, the EMA's own damping uncertainties) values no parameter whose 95 % interval
misses the truth (eta_normal 0.06, zeta0 0.004, no loss in the other directions); the diagnosis on the
EMA's own uncertainties names the hidden em_preload with an interval that holds it and a c_hat in [0.5, 2],
and the same modes with one noise stated at half give a c_hat outside.  Its time is printed, not asserted (a speed
target is a benchmark's, not a test's).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_hammer_test_example_runs_and_recovers_the_joints():
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "examples/hammer_test/run.py"], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = yaml.safe_load((ROOT / "examples/hammer_test/work/summary.yaml").read_text())
    print(f"hammer_test example: {summary['seconds']:.1f} s, modes {summary['modes']}, "
          f"error/sigma {summary['error_over_sigma']}")
    assert summary["data_check"] == []
    z = summary["error_over_sigma"]
    assert len(z) >= 5 and all(abs(v) <= 3 for v in z)  # the merged modes too: their sigma says so
    for name in ("k_normal_N_per_m3", "k_lateral_N_per_m3"):
        fit = summary["identified"][name]
        assert fit["low"] <= fit["truth"] <= fit["high"], (name, fit)
    # the joint damping: a valued parameter holds the truth (a loss factor the truth lacks is 0: in the interval
    # or at its lower end, which is cut at 0); one the fit calls not identifiable says why.  On this rig's six
    # paired modes every column of the weighted design is collinear with the others (R^2 0.995-0.9994), but the
    # EMA's 0.1-0.3 % damping uncertainties still determine zeta0 and the normal loss factor, the two the truth
    # has: both must be valued (jointid.identification.collinearity.valued).
    damping = summary["joint_damping_power_off"]
    assert damping["n_modes"] == len(z) and damping["noise_source"].startswith("stated")
    for key in ("zeta0", "eta_normal", "eta_lateral", "eta_feed"):
        d = damping[key]
        if d["value"] is None:
            assert key not in ("zeta0", "eta_normal") and d["note"].startswith("not identifiable"), (key, d)
        else:
            assert d["low"] <= d["truth"] <= d["high"], (key, d)
    assert damping["zeta0"]["truth"] == 0.004 and damping["eta_normal"]["truth"] == 0.06
    # the diagnosis of both states, on the EMA's own per-mode uncertainties (no noise typed in anywhere),
    # names the effect hidden in power_on, and its interval holds the truth
    truth_beta = yaml.safe_load((ROOT / "examples/hammer_test/truth.yaml").read_text())["effects"]["em_preload"]["beta"]
    measured = summary["diagnosis_measured_noise"]
    assert measured["explained_by"] == "em_preload", measured
    assert measured["low"] <= truth_beta <= measured["high"], measured
    # the noise is measured, not stated: the misfit is at the EMA's noise; stated by hand at half, it is not
    assert 0.5 <= measured["c_hat"] <= 2.0, measured
    assert not 0.5 <= summary["diagnosis_half_stated_noise"]["c_hat"] <= 2.0, summary["diagnosis_half_stated_noise"]
