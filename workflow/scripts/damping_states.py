"""Snakemake adapter: each state's identified joint damping against the reference state's (does the
attraction change the joint loss factor?)."""
from jointid.stages.runner import run_script
from jointid.stages import damping_states

run_script(snakemake, lambda cfg, inp, out: damping_states.run_damping_states(list(inp.params), out.json),
           provenance=True)
