"""Determinism: two runs give byte-identical results (the second one interrupted during the DOE and
resumed up to the first response surface; under ``make test-all`` also a second whole run);
provenance is the only wall-clock field."""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

import pytest
import yaml

from conftest import REPO, STATES, file_hashes, is_wall_clock, normalised
from jointid.config import ConfigStamp, config_hash, load_config
from jointid.reporting.provenance import PACKAGES, provenance, provenance_path, write_provenance

BYTE_IDENTICAL = ("results/**/*",)  # every result file, arrays (npz), mesh (vtu), figures included


@pytest.fixture(scope="module")
def cfg():
    overrides = yaml.safe_load((REPO / "tests" / "coarse_config.yaml").read_text())
    return load_config(REPO / "config.yaml", overrides=overrides)


# ------------------------------------------------------------------ provenance
def test_provenance_record_fields(cfg, tmp_path):
    rec = provenance(ConfigStamp.of(cfg), repo=tmp_path)  # tmp_path is no git checkout
    assert rec["git_commit"] == "unknown" and rec["git_dirty"] is None
    assert rec["config_hash"] == config_hash(cfg) and re.fullmatch(r"[0-9a-f]{12}", rec["config_hash"])
    assert rec["config_sections"] == sorted(cfg)
    assert set(rec["packages"]) == set(PACKAGES) >= {"jointid", "numpy", "scipy", "scikit-fem",
                                                     "pandas", "snakemake"}
    for dist in ("numpy", "scipy", "scikit-fem", "pandas", "snakemake"):
        assert rec["packages"][dist] == metadata.version(dist)
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", rec["python"])
    stamp = datetime.strptime(rec["timestamp_utc"], "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=timezone.utc)
    assert abs((datetime.now(timezone.utc) - stamp).total_seconds()) < 120


def test_provenance_git_commit_of_a_checkout(cfg):
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("the repository is not a git checkout here")
    rec = provenance(ConfigStamp.of(cfg), repo=REPO)
    assert rec["git_commit"] == head.stdout.strip() and rec["git_where"] == "given"
    assert isinstance(rec["git_dirty"], bool)


def test_provenance_config_hash_follows_the_config(cfg):
    changed = json.loads(json.dumps(cfg))
    changed["identify"]["frequency_uncertainty_pct"] = 2.0
    assert provenance(ConfigStamp.of(changed))["config_hash"] != provenance(ConfigStamp.of(cfg))["config_hash"]
    sub = {k: cfg[k] for k in ("rig", "joints")}
    assert provenance(ConfigStamp.of(sub))["config_hash"] == config_hash(sub)


def test_write_provenance_beside_the_table(cfg, tmp_path):
    table = tmp_path / "tables" / "table2_power_off.csv"
    table.parent.mkdir()
    table.write_text("order,freq_Hz\n1,344.3\n")
    inp = tmp_path / "verify.csv"
    inp.write_text("x\n1\n")
    out = write_provenance(table, ConfigStamp.of(cfg), inputs=[inp, tmp_path / "absent.csv"], repo=tmp_path)
    assert out == provenance_path(table) == table.with_name("table2_power_off.csv.provenance.json")
    rec = json.loads(out.read_text())
    assert rec["table"] == "table2_power_off.csv"
    assert rec["table_sha256"] == hashlib.sha256(table.read_bytes()).hexdigest()
    assert rec["inputs"] == {str(inp): hashlib.sha256(inp.read_bytes()).hexdigest(),
                             str(tmp_path / "absent.csv"): "missing"}
    assert rec["git_commit"] == "unknown" and rec["config_hash"] == config_hash(cfg)
    assert sorted(p.name for p in table.parent.iterdir()) == ["table2_power_off.csv",
                                                               "table2_power_off.csv.provenance.json"]
    # rewriting replaces the record; apart from the time stamp it is reproducible
    again = json.loads(write_provenance(table, ConfigStamp.of(cfg), inputs=[inp, tmp_path / "absent.csv"],
                                        repo=tmp_path).read_text())
    rec.pop("timestamp_utc"), again.pop("timestamp_utc")
    assert again == rec


# ------------------------------------------------------------------ two runs
def _reproducible_part(path: Path) -> dict:
    """A provenance record without the fields that legitimately change between runs (time, git; the
    SHA-256 of a file that holds wall-clock time, whose bytes are compared normalised instead)."""
    rec = json.loads(path.read_text())
    result = "results/" + Path(path).as_posix().split("/results/", 1)[-1][:-len(".provenance.json")]
    wall_clock = is_wall_clock(result)
    drop = ("timestamp_utc", "git_commit", "git_dirty") + (("table_sha256",) if wall_clock else ())
    return {k: v for k, v in rec.items() if k not in drop}


# outputs of the rules that write provenance sidecars (workflow/scripts: run_script(provenance=True))
WITH_PROVENANCE = (
    "results/modal/all.csv", "results/modal/all.npz",
    "results/surface/model.json", "results/surface/diagnostics.csv",
    "results/modal/zoom/all.csv", "results/modal/zoom/all.npz",
    "results/surface/zoom/model.json", "results/surface/zoom/diagnostics.csv",
    *(f"results/identify/{s}/{f}" for s in STATES for f in ("scout.json", "params.json", "verify.csv")),
    *(f"results/harmonic/{s}/{f}" for s in STATES for f in ("frf.csv", "dynamic_stiffness.json", "modes.npz",
                                                                     "drive_points.npz")),
    "results/tables/table2_power_off.csv", "results/tables/table3_power_on.csv",
    "results/tables/table1_dynamic_stiffness.csv", "results/tables/table1_dynamic_stiffness.md",
    "results/tables/table1_ranges.csv", "results/tables/table1_cases.csv",
    *(f"results/mesh_check/{s}.{ext}" for s in STATES for ext in ("json", "csv")),
)


@pytest.mark.slow
def test_every_result_table_has_a_matching_provenance_sidecar(coarse_run, cfg):
    wd = coarse_run
    for rel in WITH_PROVENANCE:
        table = wd / rel
        rec = json.loads(provenance_path(table).read_text())
        assert rec["table"] == table.name and rec["table_sha256"] == _sha(table), rel
        assert re.fullmatch(r"[0-9a-f]{12}", rec["config_hash"]) and rec["config_sections"], rel
        assert rec["git_commit"] != "" and set(rec["packages"]) == set(PACKAGES), rel
        assert rec["inputs"] and "missing" not in rec["inputs"].values(), rel
        for path, digest in rec["inputs"].items():  # relative to the working directory
            assert not Path(path).is_absolute() and digest == _sha(wd / path), f"{rel}: {path}"
    # the hash is that of the config parts the rule takes: one state's settings for identify,
    # the union of the chain's parts for the tables (which have no settings of their own)
    ident = json.loads(provenance_path(wd / "results/identify/power_on/params.json").read_text())
    # harmonic: the test band and drive point, which tell the identification which model modes the
    # test would clearly have seen (identify.visible_threshold)
    # materials: the solids' coefficients are read against the model's materials (jointid.fe.solids)
    assert ident["config_sections"] == ["harmonic", "identify", "joints", "materials", "measurements", "mesh",
                                        "model", "rig", "solver", "states"]
    # mesh: the whole section (identify builds the edge levels of the mesh itself)
    one_state = {k: cfg[k] for k in ("identify", "joints", "materials", "measurements", "mesh", "model", "rig")}
    one_state["solver"] = {k: cfg["solver"][k] for k in ("n_modes", "shift_Hz", "backend", "min_freq_Hz")}
    one_state["states"] = {"power_on": cfg["states"]["power_on"]}
    one_state["harmonic"] = {k: cfg["harmonic"][k] for k in ("band_Hz", "drive_point")}
    # and the damping the resolvability rule among tied pairings reads (jointid.identification.ties)
    one_state["harmonic"]["damping"] = {k: v for k, v in cfg["harmonic"]["damping"].items()
                                        if k in ("model", "damping_ratio", "alpha_per_s", "beta_s")}
    assert ident["config_hash"] == config_hash(one_state)
    tab = json.loads(provenance_path(wd / TABLE2).read_text())
    assert {"materials", "mesh", "doe", "surface", "identify", "states"} <= set(tab["config_sections"])
    assert sorted(tab["inputs"]) == ["data/paper/paper_tables.csv", "results/identify/power_off/unpaired_visible.csv",
                                     "results/identify/power_off/verify.csv",
                                     "results/identify/power_on/unpaired_visible.csv",
                                     "results/identify/power_on/verify.csv"]


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


TABLE2 = "results/tables/table2_power_off.csv"


CHAIN = {"results/model/matrices.npz", "results/doe/points.csv", "results/modal/all.npz",
         "results/surface/model.json", "results/surface/diagnostics.csv"}
# (the edge-level model files are temp(): gone once identify and the mesh check have read them)
WHOLE = CHAIN | {"results/tables/table2_power_off.csv", "results/tables/table3_power_on.csv",
                 "results/tables/table1_dynamic_stiffness.csv", "results/identify/power_off/params.json",
                 "results/identify/power_on/params.json", "results/surface/zoom/model.json",
                 "results/doe/zoom/points.csv", "results/mesh_check/power_on.json",
                 "results/report/index.html", "results/diagnosis/paper/ranking.csv"}


def _assert_same_results(first: Path, second: Path, required: set) -> None:
    """Every result file of ``second`` (a run from a clean folder) has the bytes of ``first``'s; the
    files in ``required`` are among them.  The diagnosis' run records (history.csv, verdict.json, its
    index.html) carry the run's time stamp and timings: they must agree once those are removed.
    Provenance sidecars agree except for time stamp and git state."""
    a = {k: v for k, v in file_hashes(first, BYTE_IDENTICAL).items() if not k.endswith(".provenance.json")}
    b = {k: v for k, v in file_hashes(second, BYTE_IDENTICAL).items() if not k.endswith(".provenance.json")}
    assert required <= set(b), f"missing from the second run: {sorted(required - set(b))}"
    assert set(b) <= set(a), f"only in the second run: {sorted(set(b) - set(a))}"
    differ = sorted(k for k in b if a[k] != b[k] and not is_wall_clock(k))
    assert not differ, f"not byte-identical between the two runs: {differ}"
    differ = [k for k in b if is_wall_clock(k) and normalised(first / k) != normalised(second / k)]
    assert not differ, f"differ beyond their time stamps: {differ}"
    sidecars = sorted(second.glob("results/**/*.provenance.json"))
    assert sidecars
    for p in sidecars:
        assert _reproducible_part(p) == _reproducible_part(first / p.relative_to(second)), p.name


@pytest.mark.slow
def test_a_second_run_killed_and_resumed_is_byte_identical(coarse_run, resumed_run):
    """Two runs from clean folders give the same bytes.  The second one is ``resumed_run``: killed
    during the DOE fan-out and resumed up to the first response surface, so this also proves that
    resuming changes nothing.  All but the DOE points written before the kill are computed by its own
    fresh jobs."""
    _assert_same_results(coarse_run, resumed_run.workdir, CHAIN)


@pytest.mark.slow
@pytest.mark.extended
def test_a_second_whole_run_is_byte_identical(coarse_run, second_run):
    """The whole workflow (hypotheses, diagnosis with its run records, report) run twice from clean
    folders gives the same bytes."""
    _assert_same_results(coarse_run, second_run, WHOLE)
    assert any(is_wall_clock(k) for k in file_hashes(second_run, BYTE_IDENTICAL)), "the diagnosis ran"
    assert set(file_hashes(second_run, BYTE_IDENTICAL)) == set(file_hashes(coarse_run, BYTE_IDENTICAL))


def test_params_json_reads_back_as_the_same_bytes(coarse_run, tmp_path):
    """The identify stage writes params.json through :class:`jointid.identification.record.IdentificationRecord`;
    read back and written again, each state's file keeps every byte (the polish, its mesh extrapolation and
    the shared frequency pairing included)."""
    from jointid.identification.record import IdentificationRecord, PairedBy

    for state in STATES:
        path = coarse_run / "results" / "identify" / state / "params.json"
        rec = IdentificationRecord.read(path)
        assert rec.fe_polish is not None and rec.paired_by is PairedBy.FREQUENCY_SHARED
        rec.write(tmp_path / f"{state}.json")
        assert (tmp_path / f"{state}.json").read_bytes() == path.read_bytes()
