"""Snakemake adapter: build and verify the parametric reduced-order model (solver.method: rom)."""
from jointid.config.typed import ModelSpec
from jointid.stages.runner import run_script
from jointid.stages import modal

run_script(snakemake, lambda cfg, inp, out: modal.run_rom(
    ModelSpec.from_config(cfg), inp.matrices, inp.sheet, out.rom, out.summary), provenance=True)
