"""The shipped second example (examples/single_carriage): a mesh file made with gmsh, its config and
a synthetic dataset with a hidden effect.  The whole workflow runs on it, and the diagnosis ranks
the hidden effect first and recovers its size."""

from __future__ import annotations

import shutil
import subprocess

import pandas as pd
import pytest
import yaml

from conftest import REPO, SNAKEMAKE, copy_workflow, tail, workflow_env

pytestmark = [pytest.mark.slow, pytest.mark.extended]  # make test-all: a second whole workflow (55 s alone on 2 cores)

EXAMPLE = "examples/single_carriage"


def test_second_example_runs_end_to_end_and_ranks_its_hidden_effect_first(tmp_path):
    work = copy_workflow(tmp_path / "work")
    shutil.copytree(REPO / EXAMPLE, work / EXAMPLE)
    proc = subprocess.run([str(SNAKEMAKE), "-j2", "--configfile", f"{EXAMPLE}/config.yaml"], cwd=work,
                          capture_output=True, text=True, timeout=1800, env=workflow_env())
    assert proc.returncode == 0, tail(proc.stdout + proc.stderr)
    truth = yaml.safe_load((work / EXAMPLE / "truth.yaml").read_text())
    ranking = pd.read_csv(work / "results/single_carriage/diagnosis/measured/ranking.csv")
    first = ranking.iloc[0]
    hidden = next(iter(truth["effects"]))
    assert first["effect"] == hidden and bool(first["explains"])
    assert first["ci95_low"] <= truth["effects"][hidden]["beta"] <= first["ci95_high"]
    ladder = pd.read_csv(work / "results/single_carriage/diagnosis/measured/ladder.csv")
    before = ladder[ladder.variant == "baseline"].max_abs_error_pct.max()
    after = ladder[ladder.variant.str.startswith(f"+{hidden}")].max_abs_error_pct.max()
    assert before > 5.0 and after < 0.5  # the error falls from the model's misfit to the noise
    # the rest of the chain ran on the mesh file: tables without the paper's columns, report written
    table = pd.read_csv(work / "results/single_carriage/tables/table3_power_on.csv")
    assert table.paper_simulation_Hz.isna().all() and table.relative_error_pct.abs().max() < 2.0
    assert (work / "results/single_carriage/report/index.html").stat().st_size > 0
    assert not (work / "results/single_carriage/identify/power_off/carriage_rigidity.json").exists()  # the rig's test only
