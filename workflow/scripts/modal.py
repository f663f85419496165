"""Snakemake adapter: modal solve at one DOE point."""
from jointid.workflow import run_script
from jointid import stages

run_script(snakemake, lambda cfg, inp, out: stages.run_modal(
    cfg, inp.matrices, dict(snakemake.params.theta), out.modes))
