"""Snakemake adapter: the run model's shared reduced basis (the diagnosis's and the hypotheses' start)."""
from jointid.stages.basis import run_basis
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_basis(cfg, inp.matrices, out.basis))
