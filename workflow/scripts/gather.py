"""Snakemake adapter: gather the per-point modal results."""
from jointid.stages.runner import run_script
from jointid.stages import modal

run_script(snakemake, lambda cfg, inp, out: modal.run_gather(
    inp.sheet, list(inp.modes), out.table, out.arrays), provenance=True)
