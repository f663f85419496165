"""Determinism: two clean runs give byte-identical results; provenance is the only wall-clock field."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

import pytest
import yaml

from conftest import REPO, copy_workflow, file_hashes, run_snakemake
from jointid.config import config_hash, load_config
from jointid.provenance import PACKAGES, provenance, provenance_path, write_provenance

BYTE_IDENTICAL = ("results/**/*",)  # every result file, arrays (npz) and mesh (vtu) included


@pytest.fixture(scope="module")
def cfg():
    overrides = yaml.safe_load((REPO / "tests" / "coarse_config.yaml").read_text())
    return load_config(REPO / "config.yaml", overrides=overrides)


# ------------------------------------------------------------------ provenance
def test_provenance_record_fields(cfg, tmp_path):
    rec = provenance(cfg, repo=tmp_path)  # tmp_path is no git checkout
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
    rec = provenance(cfg, repo=REPO)
    assert rec["git_commit"] == head.stdout.strip() and rec["git_where"] == "given"
    assert isinstance(rec["git_dirty"], bool)


def test_provenance_config_hash_follows_the_config(cfg):
    changed = json.loads(json.dumps(cfg))
    changed["identify"]["frequency_uncertainty_pct"] = 2.0
    assert provenance(changed)["config_hash"] != provenance(cfg)["config_hash"]
    sub = {k: cfg[k] for k in ("rig", "joints")}
    assert provenance(sub)["config_hash"] == config_hash(sub)


def test_write_provenance_beside_the_table(cfg, tmp_path):
    table = tmp_path / "tables" / "table2_power_off.csv"
    table.parent.mkdir()
    table.write_text("order,freq_Hz\n1,344.3\n")
    inp = tmp_path / "verify.csv"
    inp.write_text("x\n1\n")
    out = write_provenance(table, cfg, inputs=[inp, tmp_path / "absent.csv"], repo=tmp_path)
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
    again = json.loads(write_provenance(table, cfg, inputs=[inp, tmp_path / "absent.csv"],
                                        repo=tmp_path).read_text())
    rec.pop("timestamp_utc"), again.pop("timestamp_utc")
    assert again == rec


# ------------------------------------------------------------------ two clean runs
def _reproducible_part(path: Path) -> dict:
    """A provenance record without the fields that legitimately change between runs (time, git)."""
    rec = json.loads(path.read_text())
    return {k: v for k, v in rec.items() if k not in ("timestamp_utc", "git_commit", "git_dirty")}


@pytest.mark.slow
def test_two_clean_runs_are_byte_identical(coarse_run, tmp_path):
    first = coarse_run
    second = copy_workflow(tmp_path / "second")
    run_snakemake(second, "-j2", check=True)

    a, b = file_hashes(first, BYTE_IDENTICAL), file_hashes(second, BYTE_IDENTICAL)
    a = {k: v for k, v in a.items() if not k.endswith(".provenance.json")}
    b = {k: v for k, v in b.items() if not k.endswith(".provenance.json")}
    assert set(a) == set(b)
    assert {"results/tables/table2_power_off.csv", "results/tables/table3_power_on.csv",
            "results/identify/power_off/params.json", "results/identify/power_on/params.json",
            "results/surface/model.json", "results/surface/diagnostics.csv",
            "results/modal/all.npz", "results/model/matrices.npz"} <= set(a)
    differ = sorted(k for k in a if a[k] != b[k])
    assert not differ, f"not byte-identical between two clean runs: {differ}"
    # provenance sidecars (once the stages write them) agree except for time stamp and git state
    for p in sorted(first.glob("results/**/*.provenance.json")):
        assert _reproducible_part(p) == _reproducible_part(second / p.relative_to(first)), p.name
    shutil.rmtree(second / "results")  # 30+ MB per run: free the shared disk early
