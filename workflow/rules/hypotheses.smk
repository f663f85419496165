# Reconstruction hypotheses (docs/reconstruction.md, "Hypotheses"): each `hypotheses.<name>` of
# config.yaml fitted to the run's measured states under the linked two-state law, then ranked by AICc.
#   results/hypotheses/<name>/fit.json      one hypothesis (parameters, intervals, errors, misfits)
#   results/hypotheses/ranking.csv          ranked by AICc (+ spread.csv, ranking.md)
#   results/hypotheses/next_measurements.csv the measurement that would best narrow the admissible
#                                           hypotheses' joint parameters (also in ranking.md)
#   results/hypotheses/linked.json          the best hypothesis's linked fit per state, with the
#                                           rigidity of a carriage on its rail under its joints
# A hypothesis that changes the model itself (geometry, support kind, mesh) builds its own model in its own
# job (rule hypothesis).  With solver.method: reduced (the default, for a laptop) those that change only
# coefficients of the run's model (materials, masses, forces, effects, the contact law) are fitted together
# in one job (rule hypotheses_run_model): the model loaded once, one set of terms, one reduced solver grown
# from fit to fit, then ranked with the others (their jobs first) so that only the admissible ones get the
# certificate's Sturm count and the next measurement's predictions.  Those with a model of their own are then
# fitted in their jobs without it (results/hypotheses/<name>/search.json); the job on the run's model ranks them
# with its own, fits an admissible one again on its model to certify it, and writes every fit.json.  With full
# (a cluster, docs/scale-out.md), or with no hypothesis on the run's model, each is a job of its own, and each
# is certified.

from jointid.config.hypotheses import check_hypotheses, cost_rank, needs_own_model
from jointid.diagnosis.effects import check_hypothesis_effects
from jointid.config import rule_keys as keys

HYPOTHESES = check_hypotheses(config, check_hypothesis_effects)  # a bad hypothesis stops the run before any job
SHARED = [n for n in HYPOTHESES if config["solver"]["method"] == "reduced"
          and not needs_own_model(config["hypotheses"][n], config)]  # fitted together (rule hypotheses_run_model)
SEPARATE = [n for n in HYPOTHESES if n not in SHARED]  # a job each (rule hypothesis)
# with a job on the run's model, the separate jobs leave their certificate to it (rule hypotheses_run_model)
APART = f"{R}/hypotheses/{{name}}/search.json" if SHARED else f"{R}/hypotheses/{{name}}/fit.json"
RULE_WILDCARDS["hypothesis"] = {"name": SEPARATE}  # the Snakefile's ARTIFACTS: search.json of these only


def _hypotheses_cfg(names):
    cfg = sections(config, *[k for k in keys.HYPOTHESIS if k != "hypotheses"])
    cfg["hypotheses"] = {n: config["hypotheses"][n] for n in names}
    return cfg


def _on_run_model(path):
    """The input function of ``path`` (the run's model file, its shared basis: rules mesh, basis.smk) for a
    hypothesis on the run's model; none for one that builds its own, whose job then needs neither and starts
    beside rule mesh, on the core that would wait for it."""
    return lambda wc: [] if needs_own_model(config["hypotheses"][wc.name], config) else [path]


def _hypothesis_priority(wildcards, input):
    """Longest job first among the hypotheses (:func:`jointid.config.hypotheses.cost_rank`), below the
    diagnosis's priority and above the chain's (see the Snakefile)."""
    return PRIORITY_HYPOTHESES + cost_rank(config, wildcards.name)


if SHARED:

    rule hypotheses_run_model:
        input:
            matrices=rules.mesh.output.matrices,
            dataset=_run_datasets(),
            basis=BASIS,
            others=expand(APART, name=SEPARATE),  # ranked with these, certified here if admissible
        output:
            fits=expand(f"{R}/hypotheses/{{name}}/fit.json", name=SHARED),
            apart=expand(f"{R}/hypotheses/{{name}}/fit.json", name=SEPARATE),
        params:
            cfg=_hypotheses_cfg(SHARED + SEPARATE),
            shared=SHARED,
            separate=SEPARATE,
        log:
            f"{LOGS}/hypotheses/run_model.log",
        benchmark:
            f"{BENCH}/hypotheses/run_model.tsv"
        priority: PRIORITY_HYPOTHESES
        threads: 1
        resources:
            mem_mb=4500,
            runtime=30,
        script:
            "../scripts/hypotheses_run_model.py"

if SEPARATE:

    rule hypothesis:
        input:
            matrices=_on_run_model(rules.mesh.output.matrices),
            dataset=_run_datasets,
            basis=_on_run_model(BASIS),
        output:
            fit=APART,
        params:
            cfg=lambda wc: _hypotheses_cfg([wc.name]),
            certify=not SHARED,  # else left to rule hypotheses_run_model
        wildcard_constraints:
            name="|".join(SEPARATE),
        log:
            f"{LOGS}/hypotheses/{{name}}.log",
        benchmark:
            f"{BENCH}/hypotheses/{{name}}.tsv"
        priority: _hypothesis_priority
        threads: 1
        resources:
            mem_mb=4500,
            runtime=20,
        script:
            "../scripts/hypothesis.py"

if HYPOTHESES:

    rule hypotheses:
        input:
            fits=expand(f"{R}/hypotheses/{{name}}/fit.json", name=HYPOTHESES),
        output:
            ranking=f"{R}/hypotheses/ranking.csv",
            spread=f"{R}/hypotheses/spread.csv",
            md=f"{R}/hypotheses/ranking.md",
            linked=f"{R}/hypotheses/linked.json",
            ranges=f"{R}/hypotheses/reconstruction.csv",
            next=f"{R}/hypotheses/next_measurements.csv",
        params:
            cfg=sections(config, *keys.RANKING),
        log:
            f"{LOGS}/hypotheses/ranking.log",
        priority: PRIORITY_CHECKS  # only the report waits for it: after the chain's jobs (see the Snakefile)
        threads: 1
        script:
            "../scripts/rank_hypotheses.py"

    EXTRA_TARGETS.append(f"{R}/hypotheses/ranking.csv")
