"""Snakemake adapter: write the DOE sample sheet."""
from jointid.stages.runner import run_script
from jointid.stages import doe

run_script(snakemake, lambda cfg, inp, out: doe.run_doe(cfg, out.sheet))
