"""Snakemake adapter: rank the fitted reconstruction hypotheses by QAICc, with the reconstruction ranges."""
from jointid.config.hypotheses import RankingOptions
from jointid.stages.hypotheses import ADMISSIBLE_DELTA_AICC, run_ranking
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_ranking(
    RankingOptions.from_config(cfg, ADMISSIBLE_DELTA_AICC), list(inp.fits), out.ranking, out.spread, out.md,
    out.linked, out.ranges, out.next))
