"""Snakemake adapter: the current model of one registered dataset (baseline and configured effects
calibrated, per-state errors), without the candidate search of the full diagnosis."""
import os

from jointid.config.typed_diagnosis import DiagnoseJob
from jointid.stages.diagnosis import run_current
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_current(
    DiagnoseJob.from_config(cfg), cfg["dataset"]["path"], inp.matrices, os.path.dirname(out.ladder),
    subspace=snakemake.params.subspace, basis=inp.basis))
