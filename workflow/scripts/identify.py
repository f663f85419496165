"""Snakemake adapter: identify the joint parameters of one state on the surfaces."""
from jointid.workflow import run_script
from jointid import stages

run_script(snakemake, lambda cfg, inp, out: stages.run_identify(
    cfg, snakemake.wildcards.state, inp.surface, inp.points, out.params, inp.matrices,
    rom=inp.get("rom")), provenance=True)
