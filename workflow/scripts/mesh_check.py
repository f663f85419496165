"""Snakemake adapter: identified parameters of one state re-solved on a refined mesh (rule mesh_check)."""
from jointid.config.options import MeshCheckOptions
from jointid.stages.runner import run_script
from jointid.stages.meshcheck import run_mesh_check

run_script(snakemake, lambda cfg, inp, out: run_mesh_check(
    MeshCheckOptions.from_config(cfg), snakemake.wildcards.state, inp.params, inp.verify, inp.matrices, out.json, out.csv,
    modes_npz=inp.modes), provenance=True)
