# The run model's shared reduced basis (src/jointid/stages/basis.py): built once, the start of the
# diagnosis and of every hypothesis on the run's model (each used to build the same one itself).
#   results/model/diagnosis_basis.npz

from jointid.config import rule_keys as keys


def _basis_cfg():
    cfg = sections(config, *keys.BASIS)
    named = {(c or {}).get("dataset") for c in config["states"].values()} & set(config.get("datasets") or {})
    if named:  # a state measured in a registered dataset: its entry (and only those)
        cfg["datasets"] = {n: config["datasets"][n] for n in sorted(named)}
    return cfg


def _run_datasets(wc=None):
    """The files of the run's measured datasets (the basis's reference point and mode count)."""
    import os

    folders = {dataset_folder(config, s) for s in config["states"]}
    names = ("modes.csv", "shapes.csv", "conditions.yaml")
    return sorted(os.path.join(f, n) for f in folders for n in names if os.path.exists(os.path.join(f, n)))


BASIS = f"{R}/model/diagnosis_basis.npz"


rule diagnosis_basis:
    input:
        matrices=rules.mesh.output.matrices,
        dataset=_run_datasets(),
    output:
        basis=BASIS,
    params:
        cfg=_basis_cfg(),
    log:
        f"{LOGS}/diagnosis_basis.log",
    benchmark:
        f"{BENCH}/diagnosis_basis.tsv"
    priority: PRIORITY_LONG
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    script:
        "../scripts/diagnosis_basis.py"
