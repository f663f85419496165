"""Snakemake adapter: build and cache the FE model of the rig."""
from jointid.config.typed import ModelSpec
from jointid.stages.runner import run_script
from jointid.stages import model

run_script(snakemake, lambda cfg, inp, out: model.run_mesh(
    ModelSpec.from_config(cfg), out.matrices, out.points, out.vtu, summary_json=out.summary))
