"""Snakemake adapter: write the DOE sample sheet."""
from jointid.stages.runner import run_script
from jointid.stages import core as stages

run_script(snakemake, lambda cfg, inp, out: stages.run_doe(cfg, out.sheet))
