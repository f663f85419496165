"""Snakemake adapter: the model with one or two more edge-refinement levels (mesh.extrapolate_edges)."""
from jointid.stages.runner import run_script
from jointid.stages import model

run_script(snakemake, lambda cfg, inp, out: model.run_mesh(
    cfg, out.matrices, extra_edge_levels=int(snakemake.wildcards.extra)))
