"""Measured FRFs against the model's (issue 40, item 3): FRAC, CSAC/CSF and the log-magnitude residual on
analytic FRFs, the measured drive-point dynamic stiffness of one mode against its exact value, the harmonic
stage on a synthetic dataset with a drive-point FRF (coarse rig, at the truth and off it), and the UFF 58
round trip."""

import copy
import json
import warnings
from types import SimpleNamespace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import REPO, diagnosis_rig
from jointid.correlate.frf import (COMPARE_COLUMNS, compare_frf, compare_table, csac, csf, frac, frf_on_grid,
                                   frf_scale_factor, log_magnitude_residual)
from jointid.config.options import HarmonicOptions
from jointid.errors import DataError
from jointid.response.harmonic import dynamic_stiffness
from jointid.response.measured import measured_dynamic_stiffness, stiffness_frame
from conftest import truth_settings

F = np.linspace(100.0, 1500.0, 701)


def sdof(f, fn=600.0, zeta=0.02, k=2.0e7):
    """Receptance (m/N) of one mode, 1 / (k - w^2 m + i w c), m = k / wn^2, c = 2 zeta sqrt(k m)."""
    m = k / (2 * np.pi * fn) ** 2
    c = 2 * zeta * np.sqrt(k * m)
    w = 2 * np.pi * np.asarray(f, float)
    return 1.0 / (k - w**2 * m + 1j * w * c)


# ------------------------------------------------------------------ criteria
def test_frac_of_identical_and_scaled_frfs_is_one():
    H = sdof(F) + 0.3 * sdof(F, fn=1100.0, zeta=0.03)
    assert frac(H, H) == pytest.approx(1.0, abs=1e-12)
    assert frac(H, (2.5 - 1.0j) * H) == pytest.approx(1.0, abs=1e-12)  # scale-invariant, complex factors too
    assert frf_scale_factor(H, (2.5 - 1.0j) * H) == pytest.approx(2.5 - 1.0j, rel=1e-12)
    assert frac(H, np.conj(H)) < 0.9  # the phase counts: a conjugate is not a scaled copy


def test_csac_is_one_and_csf_the_amplitude_criterion_of_a_scaled_frf_set():
    """Model = s x measurement at three DOFs: CSAC(w) = 1 at every line; CSF(w) = 2s/(1+s^2) (Zang, Grafe &
    Imregun's amplitude criterion, 1 only at s = 1 and the same for s and 1/s); the scale itself is
    frf_scale_factor."""
    X = np.column_stack([sdof(F), -0.4 * sdof(F), 0.1 * sdof(F, fn=1100.0)])
    for s in (1.0, 3.0, 1 / 3.0, 0.8):
        np.testing.assert_allclose(csac(X, s * X), 1.0, atol=1e-12)
        np.testing.assert_allclose(csf(X, s * X), 2 * s / (1 + s**2), rtol=1e-12)
        assert frf_scale_factor(X, s * X) == pytest.approx(s, rel=1e-12)
    Y = X * np.array([1.0, -1.0, 1.0])  # the second DOF's sign flipped: a different shape
    c = csac(X, Y)
    assert np.all(c < 1 - 1e-3) and np.all(c >= 0)


def test_frac_falls_as_the_model_resonance_shifts():
    """A model resonance shifted by a fraction d: FRAC < 1, falling with d.  Near resonance each FRF is a
    Lorentzian 1/(wn - w + i zeta wn) (times 1/2wn) and their overlap over a wide band is 1/(1 + (d/2zeta)^2);
    the 1/w factor and the tails make the true value a little higher, by 3 % at d = 5 % (zeta 0.02)."""
    H = sdof(F)
    shifts = (0.0, 0.005, 0.01, 0.02, 0.05)
    fr = [frac(H, sdof(F, fn=600.0 * (1 + d))) for d in shifts]
    assert fr[0] == pytest.approx(1.0, abs=1e-12)
    assert all(a > b for a, b in zip(fr, fr[1:])), fr
    np.testing.assert_allclose(fr, [1 / (1 + (d / (2 * 0.02)) ** 2) for d in shifts], rtol=0.04)


def test_log_magnitude_residual_in_decades_and_db():
    H = sdof(F)
    f, r, rms = log_magnitude_residual(F, H, 10 * H, band_Hz=(300.0, 900.0))
    assert f.min() >= 300.0 and f.max() <= 900.0 and f.size == np.count_nonzero((F >= 300) & (F <= 900))
    np.testing.assert_allclose(r, 1.0, rtol=1e-12)
    assert rms == pytest.approx(1.0)
    assert compare_frf(F, H, F, 10 * H)["log_rms_dB"] == pytest.approx(20.0)
    assert compare_frf(F, H, F, H)["log_rms_dB"] == pytest.approx(0.0, abs=1e-12)


def test_model_is_interpolated_onto_the_measured_lines():
    fine = np.linspace(50.0, 1600.0, 20001)
    Hf = sdof(fine)
    on = frf_on_grid(fine, Hf, F)
    np.testing.assert_allclose(on, sdof(F), rtol=2e-3)  # linear interpolation on a 0.08 Hz grid
    np.testing.assert_array_equal(frf_on_grid(F, sdof(F), F[::7]), sdof(F)[::7])  # exact at grid lines
    assert compare_frf(F, sdof(F), fine, Hf)["frac"] > 0.99999
    with pytest.raises(DataError, match="outside the model grid"):
        frf_on_grid(F[10:], sdof(F[10:]), F)


def test_compare_table_columns_and_state_criteria():
    X = [sdof(F), -0.4 * sdof(F)]
    curves = [{"state": "s", "point": p, "direction": "y", "f_meas_Hz": F, "H_meas": h, "f_model_Hz": F,
               "H_model": 2.0 * h} for p, h in zip(("T05", "T06"), X)]
    t = compare_table(curves)
    assert list(t.columns) == COMPARE_COLUMNS
    np.testing.assert_allclose(t["frac"], 1.0, atol=1e-12)
    np.testing.assert_allclose(t["csac"], 1.0, atol=1e-12)
    np.testing.assert_allclose(t["csf"], 2 * 2 / (1 + 4), rtol=1e-12)
    np.testing.assert_allclose(t["log_rms_dB"], 20 * np.log10(2.0), rtol=1e-12)
    assert t["n_freq"].tolist() == [F.size, F.size]


# ------------------------------------------------------------------ measured dynamic stiffness
@pytest.mark.parametrize("zeta", [0.01, 0.02, 0.05])
def test_measured_dynamic_stiffness_of_one_mode_is_exact(zeta):
    """|K|^2 = (k - m w^2)^2 + c^2 w^2, a parabola in w^2: its minimum is 4 zeta^2 k^2 (1 - zeta^2) at
    w^2 = wn^2 (1 - 2 zeta^2), so K_min = 2 zeta k sqrt(1 - zeta^2).  The refined minimum has it to 1e-6 on
    lines 7 Hz apart (a half-power band of 12 Hz at zeta 0.01); the lowest line is above it."""
    k, fn = 2.0e7, 600.0
    f = np.arange(103.0, 1500.0, 7.0)
    H = sdof(f, fn, zeta, k)
    d = measured_dynamic_stiffness(f, H, band_Hz=(300.0, 1400.0))
    exact = 2 * zeta * k * np.sqrt(1 - zeta**2)
    assert d["k_dyn_min_refined_N_per_m"] == pytest.approx(exact, rel=1e-6)
    assert d["f_at_min_refined_Hz"] == pytest.approx(fn * np.sqrt(1 - 2 * zeta**2), rel=1e-6)
    assert d["k_dyn_min_refined_N_per_mm"] == pytest.approx(exact * 1e-3, rel=1e-6)
    keep = (f >= 300) & (f <= 1400)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert d["k_dyn_min_N_per_m"] == dynamic_stiffness(f[keep], H[keep])["k_dyn_min_N_per_m"]  # Table 1's reading
    assert d["k_dyn_min_N_per_m"] >= exact and d["n_freq"] == np.count_nonzero(keep)
    tab = stiffness_frame(f, H)
    np.testing.assert_allclose(tab["K_abs_N_per_m"], 1 / np.abs(H))
    np.testing.assert_allclose(tab["K_abs_N_per_mm"], 1e-3 / np.abs(H))


# ------------------------------------------------------------------ the harmonic stage on synthetic data
TRUTH = {"k_normal_N_per_m3": 8.0e11, "k_lateral_N_per_m3": 6.0e11}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A synthetic dataset with a drive-point FRF (T05 y, 400 lines over 100-3500 Hz, every mode at zeta 0.02)
    from the coarse diagnosis rig, and the harmonic stage's config reading it (modal damping 0.02: the
    truth's)."""
    from jointid.synthetic.generate import write_synthetic
    from jointid.fe.model import save_model

    tmp = tmp_path_factory.mktemp("frf_synth")
    rig = diagnosis_rig()
    truth = {"joints": TRUTH, "states": {"power_off": {"em_force_N": 0.0}},
             "measurement": {"frf": True, "drive_point": "T05", "drive_direction": "y"}, "noise": {"seed": 1}}
    ds = write_synthetic(truth, truth_settings(truth, rig["cfg"]), tmp / "ds", model=rig["model"])
    cfg = copy.deepcopy(rig["cfg"])
    cfg["states"]["power_off"]["dataset"] = str(tmp / "ds")
    cfg["harmonic"]["damping"] = {"model": "modal", "damping_ratio": 0.02}
    save_model(rig["model"], tmp / "matrices.npz")
    return {"tmp": tmp, "cfg": cfg, "ds": ds}


def run_stage(synthetic, theta: dict, name: str) -> Path:
    from jointid.stages import harmonic as harmonic_stage

    out = synthetic["tmp"] / name
    out.mkdir()
    (out / "params.json").write_text(json.dumps({"parameters": {n: {"value": v} for n, v in theta.items()}}))
    harmonic_stage.run_harmonic(HarmonicOptions.from_config(synthetic["cfg"], "power_off"), "power_off", str(out / "params.json"),
                                str(synthetic["tmp"] / "matrices.npz"), str(out / "frf.csv"),
                                str(out / "dynamic_stiffness.json"), progress=print)
    return out


def test_synthetic_frf_matches_the_model_at_the_truth_and_not_off_it(synthetic):
    """At the truth FRAC > 0.99 and the measured drive-point K_min is Table 1's within 1 %; with the normal
    joint stiffness halved FRAC falls.  (Measured: synth's point load and its 20 modes without residual
    flexibility; model: the 10 mm hammer patch, every mode to 2.5 x 3500 Hz, the static residual.)"""
    from jointid.reporting.frf_section import frf_section_html, load_frf_section

    assert synthetic["ds"].frf is not None
    at = run_stage(synthetic, TRUTH, "truth")
    off = run_stage(synthetic, dict(TRUTH, k_normal_N_per_m3=0.5 * TRUTH["k_normal_N_per_m3"]), "off")
    t_at, t_off = pd.read_csv(at / "frf_compare.csv"), pd.read_csv(off / "frf_compare.csv")
    assert list(t_at.columns) == COMPARE_COLUMNS and t_at[["point", "direction"]].values.tolist() == [["T05", "y"]]
    print(f"\nFRAC at the truth {t_at['frac'][0]:.4f}, with k_normal halved {t_off['frac'][0]:.4f}; "
          f"log-magnitude RMS {t_at['log_rms_dB'][0]:.2f} / {t_off['log_rms_dB'][0]:.2f} dB")
    assert t_at["frac"][0] > 0.99
    assert t_off["frac"][0] < t_at["frac"][0] - 0.1
    assert t_off["log_rms_dB"][0] > t_at["log_rms_dB"][0]
    doc = json.loads((at / "frf_measured_stiffness.json").read_text())
    table1 = json.loads((at / "dynamic_stiffness.json").read_text())
    m = doc["measured"]
    print(f"measured K_min {m['k_dyn_min_refined_N_per_mm']:.1f} N/mm at {m['f_at_min_refined_Hz']:.1f} Hz "
          f"(lowest line {m['k_dyn_min_N_per_mm']:.1f} N/mm), Table 1 {table1['dynamic_stiffness_N_per_mm']:.1f} "
          f"N/mm at {table1['f_at_min_Hz']:.1f} Hz: {doc['measured_minus_table1_pct']:+.3f} %")
    assert doc["model_table1"]["dynamic_stiffness_N_per_m"] == table1["dynamic_stiffness_N_per_m"]
    assert m["k_dyn_min_refined_N_per_m"] == pytest.approx(table1["dynamic_stiffness_N_per_m"], rel=0.01)
    assert abs(doc["measured_minus_table1_pct"]) < 1.0
    assert m["k_dyn_min_refined_N_per_mm"] == pytest.approx(1e-3 * m["k_dyn_min_refined_N_per_m"])
    assert (at / "frf_overlay_measured.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    tab, stiff, figs = load_frf_section(synthetic["tmp"], ["truth", "nothing_here"])
    page = frf_section_html(tab, stiff, figs)
    assert page.count("<img") == 1 and "FRAC" in page and "Table 1 model (N/mm)" in page
    assert max(len(t.split("<th>")) - 1 for t in page.split("<table")[1:]) <= 8
    # the report reads them beside the harmonic results and gives them a section of their own
    from jointid.reporting.page import _frf_measured_html
    from jointid.stages.report import _frf_measured

    loaded = _frf_measured({"frf": [str(synthetic["tmp"] / "truth" / "frf.csv")]})
    assert loaded is not None and "FRAC" in _frf_measured_html({"frf_measured": loaded})
    assert _frf_measured({"frf": []}) is None


def test_without_frf_csv_the_declared_outputs_say_so(tmp_path):
    """data/paper is frequency-only: no comparison, and the three declared outputs of rule harmonic say "no
    measured FRF" (stale files of an earlier run with FRFs are overwritten); the report leaves the state out."""
    from jointid.reporting.frf_section import load_frf_section
    from jointid.stages.frf_compare import NO_FRF, OUTPUTS, write_frf_comparison

    d = tmp_path / "power_off"
    d.mkdir()
    for name in OUTPUTS:
        (d / name).write_text("stale")
    (d / "dynamic_stiffness.json").write_text("{}")
    opts = SimpleNamespace(dataset=str(REPO / "data" / "paper"))  # the dataset alone: it has no FRF
    assert write_frf_comparison(opts, "power_off", None, None, None, {}, {}, d / "dynamic_stiffness.json",
                                progress=lambda m: None) is None
    assert sorted(p.name for p in d.iterdir()) == sorted(["dynamic_stiffness.json", *OUTPUTS])
    tab = pd.read_csv(d / OUTPUTS[0])
    assert tab.empty and list(tab.columns) == COMPARE_COLUMNS
    assert json.loads((d / OUTPUTS[1]).read_text()) == {"state": "power_off", "available": False, "note": NO_FRF}
    assert (d / OUTPUTS[2]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert load_frf_section(tmp_path, ["power_off"]) is None


# ------------------------------------------------------------------ UFF 58
POINTS = pd.DataFrame({"point": ["T01", "T02", "B01"], "x_m": [0.0, 0.1, 0.0], "y_m": [0.2, 0.2, 0.0],
                       "z_m": [0.0, 0.0, 0.3]})


def frf_rows() -> pd.DataFrame:
    """Three FRFs of a drive at T01 y on uneven lines (two modes; one response in -x-ish sign)."""
    f = np.sort(300.0 + 3200.0 * np.random.default_rng(1).random(301))
    rows = []
    for p, d, s in (("T01", "y", 1.0), ("T02", "x", -0.3), ("B01", "z", 0.1)):
        H = s * (sdof(f, 800.0, 0.02, 3e7) + 0.5 * sdof(f, 2100.0, 0.03, 8e7))
        rows += [{"point": p, "direction": d, "freq_Hz": a, "re": h.real, "im": h.imag} for a, h in zip(f, H)]
    return pd.DataFrame(rows)


@pytest.mark.parametrize("via_folder", [False, True])
def test_uff58_frfs_round_trip_exactly(tmp_path, via_folder):
    """write_frf_uff (binary 58b) -> import_uff -> the same points, directions, frequency lines and complex
    values within 1e-12 relative, the drive point and direction in conditions.yaml; also through a
    written dataset folder (frf.csv)."""
    from jointid.data.dataset import read_dataset
    from jointid.data.uff import import_uff
    from jointid.data.uff_export import write_frf_uff

    frf = frf_rows()
    write_frf_uff(tmp_path / "t.uff", POINTS, frf, drive_point="T01", drive_direction="y")
    ds, _ = import_uff(tmp_path / "t.uff", POINTS, state="s", n_frf_modes=2,
                       out=tmp_path / "ds" if via_folder else None)
    if via_folder:
        ds = read_dataset(tmp_path / "ds", POINTS)
    assert ds.state_conditions("s")["frf_drive_point"] == "T01"
    assert ds.state_conditions("s")["frf_drive_direction"] == "y"
    got = {(p, d) for p, d in zip(ds.frf["point"], ds.frf["direction"])}
    assert got == {("T01", "y"), ("T02", "x"), ("B01", "z")}
    for (p, d), g in frf.groupby(["point", "direction"]):
        f, H = ds.frf_curve("s", p, d)
        np.testing.assert_array_equal(f, g["freq_Hz"].to_numpy())
        h0 = g["re"].to_numpy() + 1j * g["im"].to_numpy()
        assert np.max(np.abs(H - h0) / np.abs(h0)) <= 1e-12


def test_uff58_ascii_keeps_six_significant_digits_of_frequency(tmp_path):
    """The ASCII form of dataset 58 holds the abscissa in E13.5 fields: 6 significant digits (why the
    default is binary)."""
    from jointid.data.uff import import_uff
    from jointid.data.uff_export import write_frf_uff

    frf = frf_rows()
    write_frf_uff(tmp_path / "a.uff", POINTS, frf, drive_point="T01", drive_direction="y", binary=False)
    ds, _ = import_uff(tmp_path / "a.uff", POINTS, state="s", n_frf_modes=2)
    f, _ = ds.frf_curve("s", "T01", "y")
    err = np.max(np.abs(f - np.sort(frf.loc[frf["point"] == "T01", "freq_Hz"].to_numpy())) / f)
    assert 0 < err <= 5e-6
