"""Snakemake adapter: every state's identified parameters re-solved on a refined mesh (rule mesh_check)."""
from jointid.config.options import MeshCheckOptions
from jointid.stages.runner import run_script
from jointid.stages.meshcheck import run_mesh_checks

run_script(snakemake, lambda cfg, inp, out: run_mesh_checks(
    MeshCheckOptions.from_config(cfg), list(snakemake.params.states), list(inp.params), list(inp.verify), inp.matrices,
    list(out.json), list(out.csv), modes_npzs=list(inp.modes)), provenance=True)
