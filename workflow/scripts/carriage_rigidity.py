"""Snakemake adapter: one state's identified joints as a catalogue-style carriage rigidity."""
from jointid.config.options import CarriageOptions
from jointid.stages.runner import run_script
from jointid.stages.carriage import run_carriage_rigidity

run_script(snakemake, lambda cfg, inp, out: run_carriage_rigidity(
    CarriageOptions.from_config(cfg), snakemake.wildcards.state, inp.params, out.json), provenance=True)
