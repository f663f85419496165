"""Snakemake adapter: Tables 2 and 3 beside the paper's values."""
from jointid.stages.runner import run_script
from jointid.stages import tables

run_script(snakemake, lambda cfg, inp, out: tables.run_tables(
    {"power_off": inp.verify[0], "power_on": inp.verify[1]}, inp.paper or None,
    {"power_off": out.power_off, "power_on": out.power_on},
    markdown={"power_off": out.power_off_md, "power_on": out.power_on_md},
    unpaired_csvs={"power_off": inp.unpaired[0], "power_on": inp.unpaired[1]}, unpaired_out=out.unpaired))
