"""Snakemake adapter: Table 1 (dynamic stiffness in Y, power-off vs power-on) beside the paper's, and its
ranges over the table points and damping laws, and Table 1 under every admissible pairing."""
from jointid.config.options import Table1Options
from jointid.stages.runner import run_script
from jointid.stages import tables

run_script(snakemake, lambda cfg, inp, out: tables.run_table1(
    list(inp.stiffness), inp.paper or None, out.csv, out.md, points_npz=list(inp.points), opts=Table1Options.from_config(cfg),
    out_ranges=out.ranges, out_cases=out.cases, out_pairings=getattr(out, "pairings", None)), provenance=True)
