# EMA: modes from measured FRFs (jointid.ema, docs/measurement-format.md "From FRFs: EMA").
#   ema.sources.<name>: a frf.csv, hammer time histories (CSV), a UFF file with dataset 58, or a dataset
#   folder with frf.csv  ->  results/ema/<name>/dataset (a dataset folder with per-mode uncertainties)
#                             results/ema/<name>/report/{poles.csv, stabilisation_<state>.png, frf_<state>.png}
# Only the named sources run: without ema.sources (the paper's data) nothing here is scheduled.

from jointid.config.snakefile import ema_sources
from jointid.config import rule_keys as keys

EMA_SOURCES = ema_sources(config)
CFG_EMA = sections(config, *keys.EMA)


rule ema:
    input:
        source=lambda wc: EMA_SOURCES[wc.source],
    output:
        dataset=directory(f"{R}/ema/{{source}}/dataset"),
        poles=f"{R}/ema/{{source}}/report/poles.csv",
    params:
        cfg=CFG_EMA,
    wildcard_constraints:
        source="[A-Za-z][A-Za-z0-9_]*",
    log:
        f"{LOGS}/ema/{{source}}.log",
    benchmark:
        f"{BENCH}/ema/{{source}}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=10,
    script:
        "../scripts/ema.py"


EXTRA_TARGETS.extend(expand(f"{R}/ema/{{source}}/report/poles.csv", source=list(EMA_SOURCES)))
