"""Snakemake adapter: rank the fitted reconstruction hypotheses by QAICc, with the reconstruction ranges."""
from jointid.stages.hypotheses import run_ranking
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_ranking(cfg, list(inp.fits), out.ranking, out.spread, out.md,
                                                            out.linked, out.ranges, out.next))
