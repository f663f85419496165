"""Snakemake adapter: the modes of every DOE point in one job on one reduced basis (solver.method: reduced)."""
from jointid.config.typed import ModelSpec
from jointid.stages.runner import run_script
from jointid.stages import modal

run_script(snakemake, lambda cfg, inp, out: modal.run_modal_points(ModelSpec.from_config(cfg), inp.matrices, inp.sheet, list(out.modes)))
