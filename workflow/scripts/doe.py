"""Snakemake adapter: write the DOE sample sheet."""
from jointid.config.options import DoeOptions
from jointid.stages.runner import run_script
from jointid.stages import doe

run_script(snakemake, lambda cfg, inp, out: doe.run_doe(DoeOptions.from_config(cfg), out.sheet))
