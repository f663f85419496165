"""Snakemake adapter: fit one reconstruction hypothesis that builds its own model, under the linked two-state law."""
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects
from jointid.stages.hypotheses import run_hypothesis
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_hypothesis(
    HypothesisJob.from_config(cfg, snakemake.wildcards.name, check_hypothesis_effects), inp.matrices, out.fit),
    provenance=True)
