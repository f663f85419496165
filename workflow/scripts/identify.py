"""Snakemake adapter: identify the joint parameters of one state on the surfaces (rule identify), or
on the surfaces alone without the FE polish (rule scout: no model matrices among the inputs)."""
from jointid.stages.runner import run_script
from jointid.stages import identify

run_script(snakemake, lambda cfg, inp, out: identify.run_identify(
    cfg, snakemake.wildcards.state, inp.surface, inp.points, out.params, inp.get("matrices"),
    rom=inp.get("rom"), states=list(snakemake.params.states), summary_json=inp.summary), provenance=True)
