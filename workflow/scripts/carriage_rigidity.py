"""Snakemake adapter: every state's identified joints as a catalogue-style carriage rigidity."""
from jointid.config.options import CarriageOptions
from jointid.stages.runner import run_script
from jointid.stages.carriage import run_carriage_rigidities

run_script(snakemake, lambda cfg, inp, out: run_carriage_rigidities(
    CarriageOptions.from_config(cfg), list(snakemake.params.states), list(inp.params), list(out.json)), provenance=True)
