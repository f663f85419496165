# rules for the diagnosis stage: which listed physical effect does the model lack? (docs/effects.md)
#
# Every dataset registered under `datasets:` in config.yaml is diagnosed by
#   snakemake -j2 results/diagnosis/<name>/ranking.csv
# (plus ladder.csv, index.html and the other tables in the same folder); each run appends one row to
# results/history.csv.  results/diagnosis/<name>/current/ladder.csv is the quick half: the current
# model calibrated and its errors, without the candidate search.  Enabled effects (`effects:`) are
# part of the diagnosed model, so changing them reruns only these rules.  With no `datasets:` block the run's measured dataset (measurements.dataset,
# data/paper by default) is diagnosed under its folder name.

from jointid.config.datasets import registered_datasets

DIAG_DATASETS = registered_datasets(config)


def _diagnosis_inputs(wc):
    import os

    path = DIAG_DATASETS[wc.dataset]["path"]
    names = ("modes.csv", "shapes.csv", "frf.csv", "conditions.yaml")
    return [os.path.join(path, n) for n in names if os.path.exists(os.path.join(path, n))]


def _diagnosis_cfg(wc):
    cfg = sections(config, "materials", "rig", "model", "mesh", "mesh_check", "joints", "solver", "identify", "effects",
                   "diagnosis", "states", "harmonic")
    cfg["dataset"] = {"name": wc.dataset, **DIAG_DATASETS[wc.dataset]}
    return cfg


if DIAG_DATASETS:

    rule diagnose:
        input:
            matrices=rules.mesh.output.matrices,
            dataset=_diagnosis_inputs,
            basis=BASIS,  # rules/basis.smk: the start when no subspace is kept from an earlier run
        output:
            ranking=f"{R}/diagnosis/{{dataset}}/ranking.csv",
            ladder=f"{R}/diagnosis/{{dataset}}/ladder.csv",
            page=f"{R}/diagnosis/{{dataset}}/index.html",
            # written beside them on every run (jointid.reporting.diagnosis_outputs); declared so that a missing
            # one is rebuilt (mac_<state>.csv is written only for states with measured shapes)
            verdict=f"{R}/diagnosis/{{dataset}}/verdict.json",
            combinations=f"{R}/diagnosis/{{dataset}}/combinations.csv",
            next_measurements=f"{R}/diagnosis/{{dataset}}/next_measurements.csv",
            compare=f"{R}/diagnosis/{{dataset}}/compare.csv",
            current=f"{R}/diagnosis/{{dataset}}/current.csv",
            parameters=f"{R}/diagnosis/{{dataset}}/parameters.csv",
            drift=f"{R}/diagnosis/{{dataset}}/drift.csv",
            shape_residuals=f"{R}/diagnosis/{{dataset}}/shape_residuals.csv",
            point_residuals=f"{R}/diagnosis/{{dataset}}/point_residuals.csv",
            preload_curve=f"{R}/diagnosis/{{dataset}}/preload_curve.csv",
        params:
            cfg=_diagnosis_cfg,
            history=f"{R}/history.csv",
            subspace=f"{R}/diagnosis/{{dataset}}/subspace.npz",  # kept for the next run (diagnosis.reuse_subspace)
        wildcard_constraints:
            dataset="|".join(DIAG_DATASETS),
        log:
            f"{LOGS}/diagnosis/{{dataset}}.log",
        benchmark:
            f"{BENCH}/diagnosis/{{dataset}}.tsv"
        priority: PRIORITY_LONG
        threads: 1
        resources:
            mem_mb=4500,
            runtime=30,
        script:
            "../scripts/diagnose.py"

    EXTRA_TARGETS.extend(expand(f"{R}/diagnosis/{{dataset}}/ranking.csv", dataset=list(DIAG_DATASETS)))

    # the quick half of the loop (not part of `all`): the current model's ladder and errors, the same
    # numbers as the diagnosis' first ladder rows, without the candidate search
    #   snakemake -j2 results/diagnosis/<name>/current/ladder.csv
    rule current:
        input:
            matrices=rules.mesh.output.matrices,
            dataset=_diagnosis_inputs,
            basis=BASIS,
        output:
            ladder=f"{R}/diagnosis/{{dataset}}/current/ladder.csv",
            current=f"{R}/diagnosis/{{dataset}}/current/current.csv",
            compare=f"{R}/diagnosis/{{dataset}}/current/compare.csv",
        params:
            cfg=_diagnosis_cfg,
            subspace=f"{R}/diagnosis/{{dataset}}/subspace.npz",
        wildcard_constraints:
            dataset="|".join(DIAG_DATASETS),
        log:
            f"{LOGS}/diagnosis/{{dataset}}_current.log",
        benchmark:
            f"{BENCH}/current/{{dataset}}.tsv"
        threads: 1
        resources:
            mem_mb=4500,
            runtime=10,
        script:
            "../scripts/current.py"
