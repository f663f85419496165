"""Snakemake adapter: write the DOE sample sheet."""
from jointid.workflow import run_script
from jointid import stages

run_script(snakemake, lambda cfg, inp, out: stages.run_doe(cfg, out.sheet))
