"""Snakemake adapter: fit one reconstruction hypothesis under the linked two-state law."""
from jointid.stages.hypotheses import run_hypothesis
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_hypothesis(cfg, snakemake.wildcards.name, inp.matrices, out.fit),
           provenance=True)
