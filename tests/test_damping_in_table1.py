"""Table 1 and the model FRFs from the identified joint damping (issue 40: "Table 1 and the FRFs then use the
identified damping when the data carry zeta, and say 'assumed' when they do not"), and the two states compared.

Known truth on the coarse rig (jointid.synthetic.generate): hidden loss factors in the normal and the lateral joints
plus a structural zeta0, the same in both states.  The stiffness comes from the FE polish (a start off the truth),
the joint damping from the identify stage's path (joint_damping.params_entry), then the harmonic stage and rule
table1 run as in the workflow.  Checked:

* Table 1 (the band minimum at the drive point) from the identified damping is the truth's within 5 % in both
  states; the truth's value lies inside Table 1's range over the identified damping's 95 % intervals; the damping
  source says "identified" with the law's values;
* the same stiffness on frequency-only data: no joint_damping record, the configured (assumed) damping of every
  mode, the range over harmonic.damping.damping_ratio_range and Table 1 without the damping columns (the old path);
* the states compared (rule joint_damping_states): no loss factor changes with the attraction (the truth has none);
  a loss factor moved far outside its interval in one state is reported as changing.

Run with -s to see the numbers.
"""
import copy
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import diagnosis_rig
from test_joint_damping import ETA, NAMES, THETA, ZETA0, truth_file
from conftest import truth_settings

STATES = ("power_off", "power_on")


def _write_state(folder, cfg, polish, state, ds, with_damping: bool) -> dict:
    """params.json (the identify stage's ``parameters`` and, with damping ratios, ``joint_damping``) and a
    verify table pairing the measured modes with the polish's FE modes; returns the paths."""
    from jointid.config.datasets import dataset_folder
    from jointid.identification import joint_damping as jd

    folder.mkdir(parents=True)
    entry = jd.params_entry(dataset_folder(cfg, state), state, NAMES, polish, ds.freqs(state))
    assert bool(entry) == with_damping  # frequency-only data: nothing added to params.json
    params = {"parameters": {n: {"value": float(v)} for n, v in zip(NAMES, polish["theta"])}, **entry}
    (folder / "params.json").write_text(json.dumps(params))
    n = len(polish["index"])
    pd.DataFrame({"order": np.arange(1, n + 1), "fe_mode": np.asarray(polish["index"]) + 1,
                  "freq_Hz": polish["f_fe"]}).to_csv(folder / "verify.csv", index=False)
    return {"params": str(folder / "params.json"), "verify": str(folder / "verify.csv"),
            "json": str(folder / "dynamic_stiffness.json"), "points": str(folder / "drive_points.npz")}


def _run(tmp, cfg, model_file, polish, ds, name: str, with_damping: bool):
    """The harmonic stage of both states and rule table1 on one dataset; returns (Table 1, docs, paths)."""
    from jointid.stages import harmonic as harmonic_stage
    from jointid.config.options import HarmonicOptions, Table1Options
    from jointid.stages.tables import run_table1

    paths = {}
    for s in STATES:
        p = _write_state(tmp / name / s, cfg, polish[s], s, ds, with_damping)
        harmonic_stage.run_harmonic(HarmonicOptions.from_config(cfg, s), s, p["params"], model_file, str(tmp / name / s / "frf.csv"), p["json"],
                                    verify_csv=p["verify"], out_points=p["points"], progress=lambda m: None)
        paths[s] = p
    out = tmp / name / "tables"
    out.mkdir()
    df = run_table1([paths[s]["json"] for s in STATES], None, str(out / "table1.csv"), str(out / "table1.md"),
                    points_npz=[paths[s]["points"] for s in STATES], opts=Table1Options.from_config(cfg), out_ranges=str(out / "ranges.csv"),
                    out_cases=str(out / "cases.csv"))
    docs = {s: json.loads(Path(paths[s]["json"]).read_text()) for s in STATES}
    return df, docs, paths


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from jointid.data.dataset import read_dataset, write_dataset
    from jointid.synthetic.generate import synthesise
    from jointid.fe.model import save_model
    from jointid.geometry.points import dof_labels
    from jointid.config.typed import ModelSpec
    from jointid.identification.polish import PolishFit, polish_on_model

    rig = diagnosis_rig()
    cfg, model = rig["cfg"], rig["model"]
    tmp = tmp_path_factory.mktemp("damping_table1")
    save_model(model, tmp / "matrices.npz")
    damped = truth_file(5.0, 5.0)
    plain = {k: v for k, v in damped.items() if k not in ("joint_loss_factors", "zeta0")}
    plain["noise"] = {k: v for k, v in damped["noise"].items() if "damping" not in k}
    sets = {}
    for name, truth in (("damped", damped), ("frequency_only", plain)):
        syn = synthesise(truth, truth_settings(truth, cfg), model=model)
        if name == "frequency_only":  # synth writes a constant ratio for undamped truths: a test without zeta
            syn["modes"] = syn["modes"].drop(columns="damping_ratio")
        write_dataset(tmp / name / "data", syn["modes"], syn["shapes"], syn["frf"], conditions=syn["conditions"],
                      measuring_points=syn["points"])
        sets[name] = (read_dataset(tmp / name / "data"), syn["truth_damping"])
    ds = sets["damped"][0]
    assert np.array_equal(ds.freqs("power_off"), sets["frequency_only"][0].freqs("power_off"))  # same test, no zeta
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    lower = [cfg["joints"]["parameters"][n]["lower"] for n in NAMES]
    upper = [cfg["joints"]["parameters"][n]["upper"] for n in NAMES]
    spec = ModelSpec.from_config(cfg)
    polish = {s: polish_on_model(spec, model, NAMES, np.array([1.3 * THETA[NAMES[0]], 0.8 * THETA[NAMES[1]]]),
                                 PolishFit(ds.freqs(s), ds.shape_matrix(s, labels), lower, upper, sigma_rel=0.001),
                                 log=lambda m: None) for s in STATES}
    out = {}
    for name, (data, truth_damping) in sets.items():
        scfg = copy.deepcopy(cfg)
        scfg["states"] = {s: {"dataset": str(tmp / name / "data")} for s in STATES}
        out[name] = _run(tmp, scfg, str(tmp / "matrices.npz"), polish, data, name, name == "damped")
    return {"cfg": cfg, "truth": sets["damped"][1], "polish": polish, **out}


def _truth_table1(cfg, t) -> float:
    """The truth's Table 1: min |F/X| over harmonic.band_Hz at the drive point from its modes and hidden damping."""
    from jointid.response.ranges import band_minimum

    return band_minimum(cfg["harmonic"]["band_Hz"], t["freqs_Hz"], t["damping_ratio"], np.zeros(t["freqs_Hz"].size),
                        t["drive_participation"])["k_min_N_per_m"]


def _band_minimum_mm(r) -> float:
    return r.dynamic_stiffness_N_per_mm if r.status == "identified" else r.not_identified_dynamic_stiffness_N_per_mm


def test_table1_from_the_identified_damping_is_the_truths(runs, capsys):
    cfg = runs["cfg"]
    df, docs, _ = runs["damped"]
    assert df["damping_source"].tolist() == ["identified", "identified"]
    for r in df.itertuples():
        doc = docs[r.state]
        truth_k = _truth_table1(cfg, runs["truth"][r.state]) * 1e-3
        k = _band_minimum_mm(r)
        dev = k / truth_k - 1
        per_mode = doc["damping"]["per_mode"]
        g = doc["governing_mode"]
        # the truth's ratio of the governing mode (the truth's modes are the same model's at the truth stiffness)
        t = runs["truth"][r.state]
        z_true = float(t["damping_ratio"][np.argmin(np.abs(t["freqs_Hz"] - g["freq_Hz"]))])
        with capsys.disabled():
            print(f"\n{r.state}: Table 1 {k:,.0f} N/mm ({r.status}) at {r.f_at_min_Hz:.0f} Hz, truth {truth_k:,.0f} "
                  f"N/mm ({100 * dev:+.2f} %); over the identified 95 % intervals {r.k_dyn_min_low_N_per_mm:,.0f}–"
                  f"{r.k_dyn_min_high_N_per_mm:,.0f} N/mm; governing FE mode {g['fe_mode']} zeta {g['damping_ratio']:.4f} "
                  f"[{r.damping_ratio_low:.4f}, {r.damping_ratio_high:.4f}] truth {z_true:.4f}")
            print(f"  {r.damping_note}")
        assert abs(dev) < 0.05
        assert r.k_dyn_min_low_N_per_mm <= truth_k <= r.k_dyn_min_high_N_per_mm
        assert r.damping_ratio_low <= z_true <= r.damping_ratio_high
        assert r.damping_note.startswith("identified: ζ0 + Σ_j")
        assert doc["damping"]["source"] == "identified"
        assert {m["source"] for m in per_mode} <= {"identified", "rigid"}
        assert len({round(m["damping_ratio"], 6) for m in per_mode if m["source"] == "identified"}) > 3  # per mode
        assert doc["damping_range"]["damping_ratio_grid"] == ["low", "value", "high"]
    md = Path(runs["damped"][2]["power_off"]["json"].replace("power_off/dynamic_stiffness.json",
                                                               "tables/table1.md")).read_text()
    assert "identified damping's 95 % intervals" in md and "power_on: identified: ζ0" in md
    from jointid.reporting.table_sections import table1_html

    assert "Damping (identified): identified: ζ0" in table1_html({"table1": df, "table1_ranges": None})


def test_frequency_only_data_keep_the_assumed_damping(runs):
    """No zeta in the data: the configured damping (modal 0.03), the range over 0.02-0.05, no damping columns."""
    df, docs, paths = runs["frequency_only"]
    damped, _, _ = runs["damped"]
    assert "damping_source" not in df and "damping_note" not in df
    assert list(df.columns) == [c for c in damped.columns if c not in ("damping_source", "damping_note")]
    for s, doc in docs.items():
        assert "joint_damping" not in json.loads(Path(paths[s]["params"]).read_text())
        assert doc["damping"]["source"] == "assumed"
        z = {m["damping_ratio"] for m in doc["damping"]["per_mode"] if m["source"] != "rigid"}
        assert z == {runs["cfg"]["harmonic"]["damping"]["damping_ratio"]}
        assert {m["source"] for m in doc["damping"]["per_mode"]} <= {"modal", "rigid"}
    assert df["damping_ratio_low"].tolist() == [0.02, 0.02] and df["damping_ratio_high"].tolist() == [0.05, 0.05]
    md = Path(paths["power_off"]["json"].replace("power_off/dynamic_stiffness.json", "tables/table1.md")).read_text()
    assert "Damping model: `modal`" in md and "ζ0" not in md and "identified damping" not in md


def test_the_states_compared(runs, tmp_path, capsys):
    from jointid.identification.damping_law import states_comparison
    from jointid.reporting.damping_section import damping_section_html, shown
    from jointid.stages.damping_states import run_damping_states

    paths = runs["damped"][2]
    doc = run_damping_states([paths[s]["params"] for s in STATES], str(tmp_path / "states.json"))
    written = json.loads((tmp_path / "states.json").read_text())
    assert written["note"] == doc["note"] and written["available"] is True
    c = doc["comparisons"][0]
    with capsys.disabled():
        print("\n" + doc["note"] + ": " + ", ".join(
            f"{k} {v['change']:+.4g} [{v['ci95_low']:.4g}, {v['ci95_high']:.4g}]" for k, v in c["parameters"].items()))
    assert doc["available"] and doc["reference_state"] == "power_off" and c["state"] == "power_on"
    assert c["eta_changes"] is False and not any(v["changes"] for v in c["parameters"].values())
    for s in STATES:
        p = doc["states"][s]["parameters"]
        assert p["eta_normal"]["ci95_low"] <= ETA["k_normal_N_per_m3"] <= p["eta_normal"]["ci95_high"]
        assert p["zeta0"]["ci95_low"] <= ZETA0 <= p["zeta0"]["ci95_high"]
    page = damping_section_html(doc)
    assert shown(doc) and "Does the attraction change the joint loss factor?" in page and "eta_lateral" in page
    # a loss factor moved by 10 sd in one state is a change; the other parameters are not
    recs = {s: json.loads(Path(paths[s]["params"]).read_text())["joint_damping"] for s in STATES}
    on = copy.deepcopy(recs["power_on"])
    on["eta_normal"] = recs["power_off"]["eta_normal"] + 10 * recs["power_off"]["eta_normal_sd"]
    moved = states_comparison({"power_off": recs["power_off"], "power_on": on}, "power_off")["comparisons"][0]
    assert moved["eta_changes"] is True and moved["parameters"]["eta_normal"]["changes"]
    assert not moved["parameters"]["zeta0"]["changes"] and "eta_normal" in moved["text"]
    # frequency-only data: no comparison, and the report has no section
    plain = runs["frequency_only"][2]
    none = run_damping_states([plain[s]["params"] for s in STATES], str(tmp_path / "none.json"))
    assert not none["available"] and none["comparisons"] == [] and not shown(none)
    assert "no state" in none["note"]
