"""The EMA (jointid.ema): modes from measured FRFs, each with an uncertainty measured from the data.

Known truth: FRFs of an analytic modal model (six modes, 18 points x 3 directions, 1-3 references,
complex noise of 1-5 % of |H|, seeded).  The extracted modes must hold the truth within their own
stated uncertainty: we count the modes whose truth lies inside the stated 95 % interval (2 sigma) and
ask for 90 % or more, in frequency and in damping.  Bad input gets one clear error and no dataset.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jointid.data.dataset import read_dataset, validate_dataset
from jointid.ema.extract import extract_state, pole_table
from jointid.ema.options import EmaOptions
from jointid.ema.poles import lsfd, pole_from
from jointid.ema.run import run_ema
from jointid.ema.synthetic import frf_table, modal_frfs
from jointid.ema.timedata import RESPONSE_SUFFIX
from jointid.errors import DataError

JOINTID = [sys.executable, "-m", "jointid.cli"]
POINTS = [f"T{i:02d}" for i in range(1, 19)]
DOFS = [(p, d) for p in POINTS for d in "xyz"]
GRID_HZ = np.arange(4.0, 3504.0, 4.0)
CASES = [(seed, noise, n_ref) for seed, (noise, n_ref) in enumerate([(1, 1), (3, 2), (5, 3), (2, 1), (4, 2), (1, 3)])]


def truth(seed: int, n_modes: int = 6):
    """A modal model: frequencies 250-3200 Hz at least 4 % apart, damping 0.5-3 %, random shapes."""
    rng = np.random.default_rng(1000 + seed)
    while True:
        f = np.sort(rng.uniform(250, 3200, n_modes))
        if np.all(np.diff(f) / f[1:] > 0.04):
            break
    return f, rng.uniform(0.005, 0.03, n_modes), rng.standard_normal((len(DOFS), n_modes))


def case_frfs(seed, noise_pct, n_ref, state="power_off"):
    f, z, phi = truth(seed)
    refs = list(np.random.default_rng(seed).choice(len(DOFS), n_ref, replace=False))
    return modal_frfs(GRID_HZ, f, z, phi, DOFS, refs, noise_pct=noise_pct, seed=seed, state=state), (f, z, phi)


def mac(a, b):
    return float((a @ b) ** 2 / ((a @ a) * (b @ b)))


@pytest.fixture(scope="module")
def coverage():
    """Every known-truth case extracted once: per truth mode (z of frequency, z of damping, shape MAC)."""
    rows = []
    for seed, noise, n_ref in CASES:
        fs, (f, z, phi) = case_frfs(seed, noise, n_ref)
        result = extract_state(fs, EmaOptions.from_section(n_bootstrap=20), log=lambda *_: None)
        table = pole_table(result)
        for m in range(len(f)):
            k = int(np.argmin(np.abs(table["freq_Hz"] - f[m])))
            row = table.iloc[k]
            shape = result.shapes[k]
            true = np.array([phi[DOFS.index(d), m] for d in shape.dofs])
            rows.append({"seed": seed, "noise_pct": noise, "n_ref": n_ref, "f_true": f[m],
                         "found": abs(row.freq_Hz - f[m]) < 0.01 * f[m],
                         "z_freq": (row.freq_Hz - f[m]) / (row.freq_uncertainty_pct / 100 * row.freq_Hz),
                         "z_damp": (row.damping_ratio - z[m]) / (row.damping_uncertainty_pct / 100 * row.damping_ratio),
                         "mac": mac(shape.value, true), "shape_unc_pct": row.shape_uncertainty_pct})
    return pd.DataFrame(rows)


def test_every_true_mode_is_found_with_its_shape(coverage):
    assert coverage["found"].all(), coverage[~coverage["found"]]
    assert coverage["mac"].min() > 0.99, coverage.sort_values("mac").head()


def test_extracted_modes_hold_the_truth_within_their_own_uncertainty(coverage):
    within_f = float(np.mean(np.abs(coverage["z_freq"]) <= 2))
    within_z = float(np.mean(np.abs(coverage["z_damp"]) <= 2))
    one_f = float(np.mean(np.abs(coverage["z_freq"]) <= 1))
    print(f"\n{len(coverage)} modes: truth within the stated 95 % interval (2 sigma): frequency {within_f:.0%}, "
          f"damping {within_z:.0%}; within 1 sigma: frequency {one_f:.0%}")
    assert within_f >= 0.9 and within_z >= 0.9
    # the uncertainty is not inflated to pass: the errors use the interval (rms z between 0.5 and 1.5)
    rms = float(np.sqrt(np.mean(coverage["z_freq"] ** 2)))
    assert 0.5 <= rms <= 1.5, rms


def test_uncertainty_grows_with_the_noise(coverage):
    by_noise = coverage.groupby("noise_pct")["shape_unc_pct"].median()
    assert by_noise[5] > by_noise[1]


def test_lsfd_matches_sdypy_ema():
    """jointid's LSFD (written for its covariance) gives sdypy-EMA's residues."""
    from sdypy.EMA.EMA import LSFD

    fs, (f, z, _) = case_frfs(0, 1, 1)
    band = (100.0, 3400.0)
    poles = pole_from(f, z)
    ours = lsfd(fs.freq_Hz, fs.H, poles, band).A
    lo, hi = (int(np.argmin(np.abs(fs.freq_Hz - b))) for b in band)
    theirs, *_ = LSFD(poles, fs.H, fs.freq_Hz, True, True, lo, hi + 1, "receptance")
    assert np.allclose(ours, theirs, rtol=1e-6, atol=1e-9 * np.abs(theirs).max())


def test_cli_writes_a_dataset_that_jointid_data_check_accepts(tmp_path):
    fs, (f, _, _) = case_frfs(3, 2, 2)
    src = tmp_path / "frf.csv"
    frf_table(fs).to_csv(src, index=False)
    out = tmp_path / "hammer"
    proc = subprocess.run(JOINTID + ["data", "ema", str(src), "--out", str(out), "--bootstrap", "10"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "physical poles" in proc.stdout and "bootstrap over response rows" in proc.stdout
    check = subprocess.run(JOINTID + ["data", "check", str(out)], capture_output=True, text=True, timeout=120)
    assert check.returncode == 0 and "valid (power_off: 6 modes; with shapes and FRF)" in check.stdout
    ds = read_dataset(out)
    rel = ds.frequency_sigma_rel("power_off")
    assert rel.shape == (6,) and np.all(rel > 0) and np.all(rel < 1e-3)
    assert np.allclose(ds.freqs("power_off"), f, rtol=1e-3)
    assert ds.damping("power_off") is not None and ds.mode_uncertainty_pct("power_off", "shape") is not None
    report = Path(str(out) + "_ema")
    poles = pd.read_csv(report / "poles.csv")
    assert {"freq_Hz", "damping_ratio", "freq_uncertainty_pct", "mpc", "n_stable_orders"} <= set(poles.columns)
    assert (report / "stabilisation_power_off.png").stat().st_size > 10_000
    assert (report / "frf_power_off.png").stat().st_size > 10_000


def test_uff58_frfs_go_through_the_ema(tmp_path):
    from jointid.data.uff_export import write_frf_uff

    fs, (f, _, _) = case_frfs(0, 1, 1)
    table = frf_table(fs)
    pts = pd.DataFrame({"point": POINTS, "x_m": np.arange(18.0) * 0.05, "y_m": 0.0, "z_m": 0.0})
    ref_point, ref_dir = table["reference"].iloc[0].split(":")
    write_frf_uff(tmp_path / "hammer.uff", pts, table, drive_point=ref_point, drive_direction=ref_dir)
    ds, _ = run_ema(tmp_path / "hammer.uff", tmp_path / "ds", options=EmaOptions.from_section(n_bootstrap=5),
                    log=lambda *_: None)
    assert np.allclose(ds.freqs("measured"), f, rtol=1e-3)
    assert validate_dataset(tmp_path / "ds") == []
    assert set(ds.shapes["point"]) == {str(k) for k in range(1, 19)}  # node numbers without the model's points
    # with the model's points, the nodes are mapped (by name suffix, then coordinates) as the UFF importer does
    mapped, _ = run_ema(tmp_path / "hammer.uff", tmp_path / "ds_mapped", measuring_points=pts,
                        options=EmaOptions.from_section(n_bootstrap=2), log=lambda *_: None)
    assert set(mapped.shapes["point"]) == set(POINTS)
    with pytest.raises(DataError, match="UFF node 18 is not a measuring point of the model"):
        run_ema(tmp_path / "hammer.uff", tmp_path / "ds_bad", measuring_points=pts.iloc[:-1],
                options=EmaOptions.from_section(n_bootstrap=2), log=lambda *_: None)
    assert not (tmp_path / "ds_bad").exists()


# ------------------------------------------------------------------------------------------ bad input
def _expect_error(tmp_path, source, match, **kw):
    out = tmp_path / "out"
    with pytest.raises(DataError, match=match):
        run_ema(source, out, options=EmaOptions.from_section(n_bootstrap=2, **kw), log=lambda *_: None)
    assert not out.exists() and not Path(str(out) + "_ema").exists()  # no partial dataset, no report
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


@pytest.fixture()
def good_table():
    fs, _ = case_frfs(1, 1, 1)
    return frf_table(fs)


def test_nan_in_an_frf_is_an_error(tmp_path, good_table):
    good_table.loc[100, "re"] = np.nan
    good_table.to_csv(tmp_path / "frf.csv", index=False)
    _expect_error(tmp_path, tmp_path / "frf.csv", r"frf.csv:\d+: FRF T\d\d:[xyz] .*has NaN or infinite values — ")


def test_non_increasing_frequencies_are_an_error(tmp_path, good_table):
    good_table.loc[[10, 11], "freq_Hz"] = good_table.loc[[11, 10], "freq_Hz"].to_numpy()
    good_table.to_csv(tmp_path / "frf.csv", index=False)
    _expect_error(tmp_path, tmp_path / "frf.csv", "frequencies are not increasing .* — sort the lines")


def test_an_frf_without_a_reference_is_an_error(tmp_path, good_table):
    good_table.drop(columns="reference").to_csv(tmp_path / "frf.csv", index=False)
    _expect_error(tmp_path, tmp_path / "frf.csv", "have no reference .* — add a column reference")


def test_a_band_without_a_stable_pole_is_an_error(tmp_path, good_table):
    f, _, _ = truth(1)
    gap = int(np.argmax(np.diff(f)))
    band = [f[gap] * 1.08, f[gap + 1] * 0.92]  # between two modes, clear of both peaks
    good_table.to_csv(tmp_path / "frf.csv", index=False)
    _expect_error(tmp_path, tmp_path / "frf.csv", "no stable pole in .* — check that the band holds a resonance",
                  band_Hz=band)


def test_points_not_in_the_model_are_an_error(tmp_path, good_table):
    good_table.to_csv(tmp_path / "frf.csv", index=False)
    points = pd.DataFrame({"point": POINTS[:-1], "x_m": 0.0, "y_m": 0.0, "z_m": 0.0})  # T18 missing
    out = tmp_path / "out"
    with pytest.raises(DataError, match="point 'T18' is not a measuring point"):
        run_ema(tmp_path / "frf.csv", out, measuring_points=points,
                options=EmaOptions.from_section(n_bootstrap=2), log=lambda *_: None)
    assert not out.exists()


def test_bad_per_mode_uncertainty_is_reported_by_data_check(tmp_path):
    folder = tmp_path / "ds"
    folder.mkdir()
    (folder / "modes.csv").write_text("state,mode,freq_Hz,freq_uncertainty_pct\ns,1,300,0.1\ns,2,400,0\ns,3,500,inf\n")
    (folder / "conditions.yaml").write_text("source: test\nstates: {s: {em_force_N: 0.0}}\n")
    problems = validate_dataset(folder)
    assert any("modes.csv:3: freq_uncertainty_pct = 0 is not positive — give the 1-sigma" in p for p in problems)
    assert any("modes.csv:4: freq_uncertainty_pct = inf is not a finite number" in p for p in problems)


# ------------------------------------------------------------------------------------------ time data
def hammer_time_table(noise_rel: float, seed: int = 7, n_hits: int = 4) -> tuple[pd.DataFrame, np.ndarray]:
    """Hammer hits on T03:y, accelerations at six DOFs: half-sine pulses of 0.4 ms, response by modal
    superposition, noise of ``noise_rel`` of each channel's RMS (seeded)."""
    f_true, z_true = np.array([410.0, 980.0, 1730.0, 2450.0]), np.array([0.02, 0.015, 0.02, 0.012])
    rng = np.random.default_rng(seed)
    phi = rng.standard_normal((18, 4))
    dofs = [(p, d) for p in POINTS[:6] for d in "xyz"]
    fs_hz, n = 8192.0, 8192
    t = np.arange(n) / fs_hz
    w = 2 * np.pi * np.fft.rfftfreq(2 * n, 1 / fs_hz)
    wr = 2 * np.pi * f_true
    rows = []
    for hit in range(n_hits):
        amp = 100.0 * (1 + 0.2 * hit)
        force = np.where(t < 4e-4, amp * np.sin(np.pi * t / 4e-4), 0.0)
        F = np.fft.rfft(force, 2 * n)
        H = (1 / (wr**2 - w[:, None] ** 2 + 2j * z_true * wr * w[:, None])) @ (phi[7] * phi).T  # drive: T03:y
        acc = np.fft.irfft(-(w[:, None] ** 2) * H * F[:, None], 2 * n, axis=0)[:n]
        acc += noise_rel * acc.std(axis=0) * rng.standard_normal(acc.shape)
        frame = pd.DataFrame({"reference": "T03:y", "hit": hit + 1, "time_s": t,
                              "force_N": force + 1e-3 * amp * rng.standard_normal(n)})
        for j, (p, d) in enumerate(dofs):
            frame[f"{p}:{d}{RESPONSE_SUFFIX}"] = acc[:, j]
        rows.append(frame)
    return pd.concat(rows, ignore_index=True), f_true


def test_time_histories_become_h1_frfs_and_modes(tmp_path):
    table, f_true = hammer_time_table(noise_rel=0.002)
    table.to_csv(tmp_path / "hits.csv", index=False)
    lines = []
    ds, results = run_ema(tmp_path / "hits.csv", tmp_path / "ds", options=EmaOptions.from_section(
        n_bootstrap=5, band_Hz=[200, 3000]), log=lines.append)
    assert any("exponential window" in ln and "subtracted" in ln for ln in lines)
    assert np.allclose(ds.freqs("measured"), f_true, rtol=2e-3)
    assert np.allclose(ds.damping("measured"), [0.02, 0.015, 0.02, 0.012], rtol=0.15)
    assert results[0].frfs.coherence is not None


def test_coherence_below_threshold_is_an_error(tmp_path):
    table, _ = hammer_time_table(noise_rel=3.0)
    table.to_csv(tmp_path / "hits.csv", index=False)
    _expect_error(tmp_path, tmp_path / "hits.csv", r"coherence below 0.9 on \d+ % of the lines .* — check the sensor")


# ------------------------------------------------------------------------------------------ a real file
REAL_UFF = Path(__file__).resolve().parent / "data" / "real" / "pyfrf_impact_h1.uff"


def test_a_real_measured_frf_goes_through_the_ema(tmp_path):
    """pyFRF's real impact test (H1 of 5 hits, UFF 58): chart, pole table, and a dataset data check accepts."""
    out = tmp_path / "real"
    ds, results = run_ema(REAL_UFF, out, state="impact", options=EmaOptions.from_section(n_bootstrap=5, max_order=120),
                          log=lambda *_: None)
    check = subprocess.run(JOINTID + ["data", "check", str(out)], capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stderr
    poles = pd.read_csv(Path(str(out) + "_ema") / "poles.csv")
    print("\nreal FRF: " + ", ".join(f"{f:.1f} Hz (zeta {z:.4f}, +-{u:.3f} %)" for f, z, u in
                                      zip(poles.freq_Hz, poles.damping_ratio, poles.freq_uncertainty_pct)))
    assert len(poles) >= 8 and (poles.freq_uncertainty_pct > 0).all()
    assert poles.synth_error_pct.iloc[0] < 20  # the synthesised FRF follows the measured one
    assert (Path(str(out) + "_ema") / "stabilisation_impact.png").stat().st_size > 10_000


def test_a_refit_that_runs_away_keeps_the_lscf_pole_with_the_distance_as_sigma():
    from jointid.ema.refine import Refined, guarded

    fits = [Refined(1000.5, 0.010, 0.01, 1e-5, 40, True), Refined(2040.0, 0.012, 0.02, 1e-5, 40, True)]
    out = guarded(fits, [1000.0, 2000.0], [0.011, 0.013], [0.2, 0.3], [1e-4, 1e-4], tol_pct=1.0)
    assert out[0] is fits[0]  # moved 0.05 %: the refit stands
    assert (out[1].freq_Hz, out[1].zeta, out[1].sigma_freq_Hz) == (2000.0, 0.013, 40.0)
    assert out[1].row_jtj is None and "refit moved 2.00 %: LSCF pole kept" == out[1].note
