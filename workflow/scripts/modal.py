"""Snakemake adapter: modal solve at one DOE point (full FE solve, or the ROM with solver.method: rom)."""
from jointid.workflow import run_script
from jointid import stages

run_script(snakemake, lambda cfg, inp, out: stages.run_modal(
    cfg, inp.matrices, dict(snakemake.params.theta), out.modes, rom=inp.get("rom")))
