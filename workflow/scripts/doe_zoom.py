"""Snakemake adapter: the zoomed second DOE around the first-stage optima of all states."""
from jointid.config.options import DoeOptions
from jointid.stages.runner import run_script
from jointid.stages import doe

run_script(snakemake, lambda cfg, inp, out: doe.run_doe_zoom(
    DoeOptions.from_config(cfg), dict(zip(snakemake.params.states, inp.scout)), out.sheet, out.box))
