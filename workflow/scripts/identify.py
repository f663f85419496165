"""Snakemake adapter: identify the joint parameters of one state on the surfaces (rule identify), or
on the surfaces alone without the FE polish (rule scout: no model matrices among the inputs)."""
from jointid.config.options import IdentifyOptions
from jointid.stages.runner import run_script
from jointid.stages import identify

STATE, STATES = snakemake.wildcards.state, list(snakemake.params.states)
run_script(snakemake, lambda cfg, inp, out: identify.run_identify(
    IdentifyOptions.from_config(cfg, [STATE, *STATES]), STATE, inp.surface, inp.points, out.params,
    inp.get("matrices"), rom=inp.get("rom"), states=STATES, summary_json=inp.summary), provenance=True)
