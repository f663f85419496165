"""Rule ema (workflow/rules/ema.smk): a named FRF source becomes a cached dataset folder with its report, and
the paper's run schedules no EMA job."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import run_snakemake, copy_workflow, write_config
from jointid.data.dataset import read_dataset
from jointid.ema.synthetic import frf_table, modal_frfs

pytestmark = pytest.mark.slow


def test_rule_ema_writes_the_dataset_of_a_named_source_and_is_not_in_the_papers_run(tmp_path):
    work = copy_workflow(tmp_path / "work")
    dry = run_snakemake(work, "-n", "-j1", check=True)
    assert "rule ema" not in dry.stdout and "\nema " not in dry.stdout  # the paper's run: no EMA job
    dofs = [(f"T{i:02d}", d) for i in range(1, 19) for d in "xyz"]
    phi = np.random.default_rng(5).standard_normal((len(dofs), 3))
    fs = modal_frfs(np.arange(4.0, 3004.0, 4.0), [500.0, 1200.0, 2100.0], [0.01, 0.02, 0.015], phi, dofs, [1],
                    noise_pct=1.0, seed=5, state="power_off")
    frf_table(fs).to_csv(work / "hammer.csv", index=False)
    extra = write_config(work / "ema.yaml", "ema: {sources: {hammer: hammer.csv}, n_bootstrap: 3}\n")
    run_snakemake(work, "-j1", "results/ema/hammer/report/poles.csv", configs=[extra], check=True)
    ds = read_dataset(work / "results/ema/hammer/dataset")
    assert np.allclose(ds.freqs("power_off"), [500.0, 1200.0, 2100.0], rtol=1e-3)
    assert ds.frequency_sigma_rel("power_off").shape == (3,)
    assert (work / "results/ema/hammer/report/poles.csv.provenance.json").is_file()
    assert (work / "results/ema/hammer/report/stabilisation_power_off.png").is_file()
    again = run_snakemake(work, "-n", "-j1", "results/ema/hammer/report/poles.csv", configs=[extra], check=True)
    assert "Nothing to be done" in again.stdout + again.stderr  # cached
