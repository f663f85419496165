"""Snakemake adapter: fit one reconstruction hypothesis under the linked two-state law."""
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects
from jointid.stages.hypotheses import run_hypothesis
from jointid.stages.runner import run_script


def _one(inp, key):
    """The input ``key`` of a hypothesis on the run's model (an input list of one), else None (one with a
    model of its own has neither the run's model file nor its basis)."""
    got = inp.get(key)
    return got if isinstance(got, str) else (str(got[0]) if got else None)


run_script(snakemake, lambda cfg, inp, out: run_hypothesis(
    HypothesisJob.from_config(cfg, snakemake.wildcards.name, check_hypothesis_effects), _one(inp, "matrices"), out.fit,
    basis=_one(inp, "basis"), certify=snakemake.params.certify), provenance=True)
