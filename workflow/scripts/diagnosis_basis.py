"""Snakemake adapter: the run model's shared reduced basis (the diagnosis's and the hypotheses' start)."""
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.stages.basis import run_basis
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_basis(DiagnosisSettings.from_config(cfg), inp.matrices, out.basis))
