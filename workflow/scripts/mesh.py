"""Snakemake adapter: build and cache the FE model of the rig."""
from jointid.workflow import run_script
from jointid import stages

run_script(snakemake, lambda cfg, inp, out: stages.run_mesh(cfg, out.matrices, out.points, out.vtu))
