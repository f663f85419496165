"""Snakemake adapter: diagnose one registered dataset (which listed physical effect is missing)."""
import os

from jointid.config.typed_diagnosis import DiagnoseJob
from jointid.stages.diagnosis import run_diagnosis
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_diagnosis(
    DiagnoseJob.from_config(cfg), snakemake.wildcards.dataset, cfg["dataset"]["path"], inp.matrices, os.path.dirname(out.ranking),
    history_csv=snakemake.params.history, subspace=snakemake.params.subspace, basis=inp.basis))
