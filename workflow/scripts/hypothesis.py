"""Snakemake adapter: fit one reconstruction hypothesis under the linked two-state law."""
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects
from jointid.stages.hypotheses import run_hypothesis
from jointid.stages.runner import run_script


def _basis(inp):
    """The shared basis of a hypothesis on the run's model (an input list of one), else None."""
    got = inp.get("basis")
    return got if isinstance(got, str) else (str(got[0]) if got else None)


run_script(snakemake, lambda cfg, inp, out: run_hypothesis(
    HypothesisJob.from_config(cfg, snakemake.wildcards.name, check_hypothesis_effects), inp.matrices, out.fit,
    basis=_basis(inp), certify=snakemake.params.certify), provenance=True)
