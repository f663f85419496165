"""Snakemake adapter: Table 1 (dynamic stiffness in Y, power-off vs power-on) beside the paper's."""
from jointid.stages.runner import run_script
from jointid.stages import tables

run_script(snakemake, lambda cfg, inp, out: tables.run_table1(
    list(inp.stiffness), inp.paper, out.csv, out.md), provenance=True)
