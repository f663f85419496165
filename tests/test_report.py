"""Table 1, its CI check, provenance, figures, and (slow) harmonic -> table1 -> report on the coarse run."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from jointid.reporting import figures as fg
from jointid.reporting import tables as rp
from jointid.reporting.checks import check_table1
from jointid.reporting.provenance import run_record
from jointid.config import ConfigStamp, config_hash, load_config

from conftest import COARSE_RUN, REPO, STATES, clone_run, coarse_config_dict, run_snakemake

PAPER_T1 = REPO / "data" / "paper" / "paper_table1.csv"
PNG = b"\x89PNG\r\n\x1a\n"


def stiffness_doc(state, k_N_per_m, f=1400.0, static=9e8, fe_mode=4, order=2, paired_k=None):
    paired = None if paired_k is None else {
        "dynamic_stiffness_N_per_m": paired_k, "f_at_min_Hz": 2000.0, "fe_mode": 5, "freq_Hz": 2001.0,
        "description": "table pitch", "measured_order": 3, "damping_ratio": 0.03}
    status = "identified" if order else (f"not identified: the governing mode (FE mode {fe_mode}, {f * 1.001:.1f} Hz, "
                                         "table bounce) has no measured partner")
    return {"state": state, "drive_point": "T05", "direction": "y", "band_Hz": [300.0, 3500.0],
            "patch_diameter_m": 0.01, "status": status, "paired_minimum": paired,
            "dynamic_stiffness_N_per_m": k_N_per_m, "f_at_min_Hz": f,
            "static_stiffness_N_per_m": static,
            "governing_mode": {"fe_mode": fe_mode, "freq_Hz": f * 1.001, "description": "table bounce",
                               "damping_ratio": 0.03, "measured_order": order, "modal_stiffness_N_per_m": 1e9,
                               "two_zeta_k_N_per_m": 6e7, "strain_joints": 0.5},
            "damping": {"config": {"model": "modal", "damping_ratio": 0.03}, "measured": "", "why": ""}}


def write_table1(tmp_path, k_off, k_on, order_on=2):
    df = rp.table1_frame([stiffness_doc("power_off", k_off, paired_k=k_off),
                          stiffness_doc("power_on", k_on, order=order_on, paired_k=1.2 * k_off)],
                         pd.read_csv(PAPER_T1))
    path = tmp_path / "table1.csv"
    df.to_csv(path, index=False)
    return df, path


# ------------------------------------------------------------------ Table 1
def test_table1_columns_values_and_increase(tmp_path):
    df, _ = write_table1(tmp_path, 1.0e8, 1.3e8)
    assert list(df.columns[:6]) == rp.TABLE1_COLUMNS
    assert df.state.tolist() == ["power_off", "power_on"] and df.status.tolist() == ["identified"] * 2
    np.testing.assert_allclose(df.dynamic_stiffness_N_per_mm, [1.0e5, 1.3e5])
    assert df.not_identified_dynamic_stiffness_N_per_mm.isna().all()
    np.testing.assert_allclose(df.paper_dynamic_stiffness_N_per_mm, [104547, 148551])
    np.testing.assert_allclose(df.static_stiffness_N_per_mm, [9e5, 9e5])
    assert df.governing_mode.tolist() == [4, 4]
    assert np.isnan(df.increase_pct[0]) and df.increase_pct[1] == pytest.approx(30.0)
    assert df.paired_increase_pct[1] == pytest.approx(20.0)
    assert df.paper_increase_pct[1] == pytest.approx(42.09, abs=0.01)  # 148551 / 104547 - 1
    md = rp.table1_markdown(df)
    assert "this model +30.0 %; lowest peaks of paired modes +20.0 %; paper +42.1 %" in md
    assert "| power_on | identified | 130,000 | 148,551 |" in md


def test_table1_state_not_identified_keeps_its_number_apart(tmp_path):
    df, _ = write_table1(tmp_path, 1.0e8, 1.3e8, order_on=None)
    assert df.status[0] == "identified"
    assert df.status[1] == ("not identified: the governing mode (FE mode 4, 1401.4 Hz, table bounce) has no "
                            "measured partner")
    assert np.isnan(df.dynamic_stiffness_N_per_mm[1]) and np.isnan(df.increase_pct[1])
    assert df.not_identified_dynamic_stiffness_N_per_mm[1] == pytest.approx(1.3e5)
    assert df.paired_dynamic_stiffness_N_per_mm.tolist() == pytest.approx([1.0e5, 1.2e5])
    assert df.paired_governing_measured_order.tolist() == [3, 3]
    md = rp.table1_markdown(df)
    assert "— (not identified: 130,000)" in md and "not available (a state is not identified)" in md
    assert "120,000 (FE mode 5, 2001 Hz, table pitch, measured mode 3)" in md


def test_table1_static_stiffness_missing_when_K_singular(tmp_path):
    docs = [stiffness_doc("power_off", 1e8, static=None), stiffness_doc("power_on", 1.2e8, static=None)]
    df = rp.table1_frame(docs, pd.read_csv(PAPER_T1))
    assert df.static_stiffness_N_per_mm.isna().all()
    assert "n/a (K singular)" in rp.table1_markdown(df)


def test_check_table1_reports_each_problem(tmp_path):
    assert check_table1(tmp_path / "nope.csv", ranges=False) == [
        f"{tmp_path / 'nope.csv'}: missing — run `snakemake -j2 {tmp_path / 'nope.csv'}` (rule table1)"]
    _, good = write_table1(tmp_path, 1.0e8, 1.3e8)
    assert check_table1(good, ranges=False) == []
    _, bad = write_table1(tmp_path, 1.0e8, 0.9e8)
    assert check_table1(bad, ranges=False) == []  # a decrease is a finding, not a broken table
    problems = check_table1(bad, require_increase=True, ranges=False)
    assert len(problems) == 1 and "-10.0 %" in problems[0] and "not positive" in problems[0]
    _, unpaired = write_table1(tmp_path, 1.0e8, 1.3e8, order_on=None)
    assert check_table1(unpaired, ranges=False) == []
    assert "--require-increase" in check_table1(unpaired, require_increase=True, ranges=False)[0]
    df = pd.read_csv(bad)
    df.drop(columns=["governing_mode"]).to_csv(tmp_path / "cols.csv", index=False)
    assert "governing_mode missing" in check_table1(tmp_path / "cols.csv", ranges=False)[0]
    df[df.state == "power_off"].to_csv(tmp_path / "rows.csv", index=False)
    assert "no row for state power_on" in check_table1(tmp_path / "rows.csv", ranges=False)[0]
    df.assign(dynamic_stiffness_N_per_mm=[np.nan, 5.0]).to_csv(tmp_path / "nan.csv", index=False)
    assert "not a positive number" in check_table1(tmp_path / "nan.csv", ranges=False)[0]


def test_provenance_has_hash_versions_and_commit():
    cfg = load_config(REPO / "config.yaml")
    prov = run_record(ConfigStamp.of(cfg), REPO)
    assert prov["config_hash"] == config_hash(cfg) and re.fullmatch(r"[0-9a-f]{12}", prov["config_hash"])
    assert re.match(r"[0-9a-f]{40}", prov["package_commit"])
    assert prov["versions"]["numpy"] == np.__version__


# ------------------------------------------------------------------ figures
def test_figures_render_to_png():
    f = np.linspace(300, 3500, 50)
    h = 1e-8 / np.abs(1 - (f / 1500) ** 2 + 0.06j)
    frf = pd.DataFrame({"freq_Hz": f, "H_abs_m_per_N": h, "dynamic_stiffness_N_per_m": 1 / h})
    docs = {"power_off": stiffness_doc("power_off", float((1 / h).min()))}
    assert fg.png_bytes(fg.frf_overlay({"power_off": frf}, docs, {"power_off": 104547},
                                       {"power_off": [344.3, 1416.1]})).startswith(PNG)
    tab = pd.DataFrame({"order": [1, 2], "relative_error_pct": [1.0, -2.0], "paper_relative_error_pct": [3.0, 0.5]})
    assert fg.png_bytes(fg.frequency_errors({"power_off": tab, "power_on": tab}, {"power_off": 1.0})).startswith(PNG)
    points = pd.DataFrame({"point": ["T01", "T02", "T03", "T04", "B01", "B02"],
                           "part": ["table"] * 4 + ["base"] * 2,
                           "x_m": [0, 0.1, 0, 0.1, 0, 0.2], "y_m": [0.15] * 4 + [0.08] * 2,
                           "z_m": [0, 0, 0.1, 0.1, -0.5, -0.5]})
    lines = fg._grid_lines(points)
    assert sorted(len(i) for i in lines) == [2, 2, 2, 2, 2]  # 2 + 2 table lines, 1 base line
    u = np.zeros((6, 3))
    u[:4, 1] = 1.0
    assert fg.png_bytes(fg.mode_shapes(points, {"power_off": [{"title": "bounce", "u": u}]})).startswith(PNG)


# ------------------------------------------------------------------ page layout
def table_widths(page: str) -> list[int]:
    """Columns of each HTML table of ``page`` (its widest row)."""
    return [max(len(re.findall(r"<t[hd][\s>]", row)) for row in re.findall(r"<tr.*?</tr>", t, re.S))
            for t in re.findall(r"<table.*?</table>", page, re.S)]


def test_wide_frames_are_split_into_tables_of_eight_columns_at_most():
    from jointid.reporting.diagnosis_page import html_table as diagnosis_table
    from jointid.reporting.htmltable import MAX_COLUMNS, html_table

    df = pd.DataFrame({"state": ["power_off", "power_on"], **{f"c{i}": [1.5 * i, 2.5 * i] for i in range(12)},
                       "note": ["a long sentence that belongs under the table", ""]})
    page = html_table(df.drop(columns="note"), {f"c{i}": ".2f" for i in range(12)}, text_cols=("state",))
    assert MAX_COLUMNS == 8 and table_widths(page) == [8, 6]
    assert page.count(">power_off<") == 2 and ">16.50<" in page and ">27.50<" in page  # keys repeated, no value lost
    page = str(diagnosis_table(df, groups=[["c3", "c4"]], note_cols=("note",)))
    assert table_widths(page) == [3, 8, 4] and "<li>power_off — note: a long sentence" in page
    assert ">2.5<" in page and ">27.5<" in page


def test_short_verdict_is_one_sentence():
    from jointid.reporting.diagnosis_summary import short_verdict

    ranking = pd.DataFrame({"effect": ["em_preload", "base_support"], "support": ["moderately", "not"],
                            "delta_qaicc": [-8.38, -0.03], "removed_fraction": [0.468, 0.12]})
    text = short_verdict("unexplained", ranking, pd.DataFrame())
    assert text == ("No listed effect explains the residual to the noise; the best supported is em_preload "
                    "(moderately supported: ΔQAICc -8.4, it removes 47 % of the misfit).")
    assert short_verdict("em_preload", ranking).startswith("em_preload explains")
    assert short_verdict("a+b", ranking).startswith("a and b together explain")


# ------------------------------------------------------------------ the workflow (coarse)
@pytest.mark.slow
def test_harmonic_table1_and_report_on_the_coarse_run(coarse_run, tmp_path):
    wd = clone_run(coarse_run, tmp_path / "wf")
    t1 = "results/tables/table1_dynamic_stiffness.csv"
    run_snakemake(wd, "-j2", t1, "results/report/index.html", check=True)
    docs = {}
    for state in STATES:
        d = json.loads((wd / "results" / "harmonic" / state / "dynamic_stiffness.json").read_text())
        frf = pd.read_csv(wd / "results" / "harmonic" / state / "frf.csv")
        assert frf.freq_Hz.min() == 300.0 and frf.freq_Hz.max() == 3500.0 and frf.freq_Hz.is_monotonic_increasing
        assert d["dynamic_stiffness_N_per_m"] == pytest.approx(frf.dynamic_stiffness_N_per_m.min(), rel=1e-9)
        assert d["damping"]["config"] == {"model": "modal", "damping_ratio": 0.03}
        assert d["residual"]["used"] is True  # the default model is clamped: K nonsingular
        assert d["modes"]["highest_Hz"] >= 2.0 * 3500.0
        assert 0 < d["dynamic_stiffness_N_per_m"] < d["static_stiffness_N_per_m"]
        docs[state] = d
    tab = pd.read_csv(wd / t1)
    assert list(tab.columns[:6]) == rp.TABLE1_COLUMNS
    for state in STATES:
        row = tab[tab.state == state].iloc[0]
        k = docs[state]["dynamic_stiffness_N_per_m"] / 1e3
        if docs[state]["governing_mode"]["measured_order"]:
            assert row.status == "identified" and row.dynamic_stiffness_N_per_mm == pytest.approx(k, rel=1e-9)
        else:
            assert row.status.startswith("not identified: the governing mode (FE mode ")
            assert np.isnan(row.dynamic_stiffness_N_per_mm)
            assert row.not_identified_dynamic_stiffness_N_per_mm == pytest.approx(k, rel=1e-9)
        pm = docs[state]["paired_minimum"]
        if pm is not None:  # the lowest paired peak is never below the band minimum (equal to it when the
            # governing mode is paired; the CSV keeps 10 significant digits, jointid.io.write_csv)
            assert row.paired_dynamic_stiffness_N_per_mm >= k * (1 - 1e-9)
    ranges = pd.read_csv(wd / "results" / "tables" / "table1_ranges.csv")
    assert set(ranges.basis) == {"paired modes", "all modes"} and len(ranges) == 10
    assert check_table1(wd / t1) == []
    assert "paper +42.1 %" in (wd / t1).with_suffix(".md").read_text()

    page = (wd / "results" / "report" / "index.html").read_text()
    # six figures of the workflow plus the carriage against the catalogue classes (config.yaml's catalogue)
    assert page.count("src='data:image/png;base64,") == 7
    # the summary card leads: one sentence each, and the parameters figure, before any table
    card = page[page.index("<section class='card'"):page.index("</section>")]
    assert page.index("<section class='card'") < page.index("<table")
    for key in ("Max |error| after identification", "Joint stiffness, 95 % intervals", "Table 1.", "Model error σ_m",
                "Diagnosis.", "results/diagnosis/", "src='data:image/png;base64,"):
        assert key in card, key
    assert f"{tab.dynamic_stiffness_N_per_mm.iloc[0]:,.0f} N/mm (paper 104,547 N/mm)" in card
    assert max(table_widths(page)) <= 8, table_widths(page)  # no table wider than eight columns on screen
    assert "HGH25CA" in page
    # the paper's data carry frequencies only: the page says what shapes, damping ratios and FRFs would add
    for key in ("What more of the test would add", "<b>Mode shapes</b>", "<b>Damping ratios</b>",
                "<b>Measured FRFs</b>"):
        assert key in page, key
    assert not re.search(r"""(src|href)=['"](?!data:|#)""", page), "the page must not link external files"
    assert config_hash(load_config(coarse_config_dict(COARSE_RUN))) in page  # the run's configuration
    for key in ("Table 1", "Table 2", "Table 3", "104,547", f"{tab.dynamic_stiffness_N_per_mm.iloc[0]:,.0f}",
                "numpy", "k_normal_N_per_m3"):
        assert key in page, key
    for name in ("frf", "errors", "parameters", "surface", "doe", "mode_shapes"):
        assert (wd / "results" / "report" / "figures" / f"{name}.png").read_bytes().startswith(PNG)
    proc = run_snakemake(wd, "--report", "smk_report.html", check=True)
    assert (wd / "smk_report.html").stat().st_size > 10_000, proc.stdout


def test_model_modes_leave_as_vtu_and_uff(coarse_run, tmp_path):
    """The harmonic stage writes the identified model's modes for ParaView (one vector field per mode,
    the frequencies as field data) and as UFF 55 at the measuring points, which pyuff and jointid's own
    importer read back with the same frequencies and shapes."""
    import meshio
    import pyuff

    from jointid.data.uff import import_uff

    wd = clone_run(coarse_run, tmp_path / "wf")
    outs = [f"results/model/modes_{s}.{ext}" for s in STATES for ext in ("vtu", "uff")]
    run_snakemake(wd, "-j2", *outs, check=True)
    points = pd.read_csv(wd / "results" / "model" / "measuring_points.csv")
    for state in STATES:
        ref = np.load(wd / "results" / "harmonic" / state / "modes.npz")
        m = meshio.read(wd / "results" / "model" / f"modes_{state}.vtu")
        fields = sorted(k for k in m.point_data if k.startswith("mode_"))
        assert len(fields) == len(ref["freqs_Hz"]) and all(m.point_data[k].shape == (len(m.points), 3) for k in fields)
        assert np.allclose(np.ravel(m.field_data["freq_Hz"]), ref["freqs_Hz"])
        assert fields[1].startswith(f"mode_02_{ref['freqs_Hz'][1]:.0f}Hz_")
        uff = wd / "results" / "model" / f"modes_{state}.uff"
        sets = pyuff.UFF(str(uff)).read_sets()
        assert [s["type"] for s in sets[:2]] == [164, 15]
        assert np.allclose([s["freq"] for s in sets if s["type"] == 55], ref["freqs_Hz"])
        ds, _ = import_uff(uff, points, state=state, out=tmp_path / f"ds_{state}")
        assert np.allclose(ds.freqs(state), np.sort(ref["freqs_Hz"]))
        labels = [str(v) for v in ref["labels"]]
        back = ds.shape_matrix(state, labels)
        order = np.argsort(ref["freqs_Hz"], kind="stable")
        want = ref["shapes"][:, order] / np.abs(ref["shapes"][:, order]).max(axis=0)
        assert np.allclose(back / np.abs(back).max(axis=0), want, atol=1e-4)
