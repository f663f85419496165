# jointid workflow: joint-surface identification by FE model updating (see README.md).
#
# Path convention: results/<stage>/..., logs/<rule>/..., benchmarks/out/<rule>/...
# Config reaches every rule through `params: cfg=` holding only the sections that rule uses, so a
# changed value reruns exactly the stages that depend on it.

import sys
from jointid.workflowconfig import validated, sections
from jointid.stages import doe_sheet

configfile: "config.yaml"
config = validated(config)
SHEET = doe_sheet(config)
POINTS = list(SHEET["point"])
STATES = list(config["states"])
R = "results"


EXTRA_TARGETS = []  # rule files included below append their final outputs here


rule all:
    input:
        f"{R}/tables/table2_power_off.csv",
        f"{R}/tables/table3_power_on.csv",
        lambda wc: EXTRA_TARGETS,  # a function: read after the rule files below have appended


rule mesh:
    output:
        matrices=f"{R}/model/matrices.npz",
        points=f"{R}/model/measuring_points.csv",
        vtu=f"{R}/model/mesh.vtu",
    params:
        cfg=sections(config, "materials", "rig", "mesh"),
    log:
        "logs/mesh.log",
    benchmark:
        "benchmarks/out/mesh.tsv"
    resources:
        mem_mb=3000,
        runtime=10,
    script:
        "workflow/scripts/mesh.py"


rule doe:
    output:
        sheet=f"{R}/doe/points.csv",
    params:
        cfg=sections(config, "joints", "doe"),
    log:
        "logs/doe.log",
    script:
        "workflow/scripts/doe.py"


rule modal:
    input:
        matrices=rules.mesh.output.matrices,
        sheet=rules.doe.output.sheet,
    output:
        modes=f"{R}/modal/points/{{point}}.npz",
    params:
        cfg=sections(config, "rig", "joints", "solver"),
        theta=lambda wc: {n: float(SHEET.set_index("point").loc[wc.point, n]) for n in config["joints"]["parameters"]},
    log:
        "logs/modal/{point}.log",
    benchmark:
        "benchmarks/out/modal/{point}.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    script:
        "workflow/scripts/modal.py"


rule gather_modal:
    input:
        sheet=rules.doe.output.sheet,
        modes=expand(f"{R}/modal/points/{{point}}.npz", point=POINTS),
    output:
        table=f"{R}/modal/all.csv",
        arrays=f"{R}/modal/all.npz",
    params:
        cfg={},
    log:
        "logs/gather_modal.log",
    script:
        "workflow/scripts/gather.py"


rule fit_surface:
    input:
        sheet=rules.doe.output.sheet,
        arrays=rules.gather_modal.output.arrays,
    output:
        model=f"{R}/surface/model.json",
        diagnostics=f"{R}/surface/diagnostics.csv",
    params:
        cfg=sections(config, "joints", "surface", "solver", "harmonic"),
    log:
        "logs/fit_surface.log",
    script:
        "workflow/scripts/fit_surface.py"


rule identify:
    input:
        surface=rules.fit_surface.output.model,
        points=rules.mesh.output.points,
        matrices=rules.mesh.output.matrices,
        dataset=lambda wc: config["states"][wc.state].get("dataset") or config["measurements"]["dataset"],
    output:
        params=f"{R}/identify/{{state}}/params.json",
    params:
        cfg=sections(config, "rig", "joints", "identify", "states", "measurements", "solver"),
    log:
        "logs/identify/{state}.log",
    script:
        "workflow/scripts/identify.py"


rule verify:
    input:
        params=rules.identify.output.params,
        surface=rules.fit_surface.output.model,
        matrices=rules.mesh.output.matrices,
    output:
        table=f"{R}/identify/{{state}}/verify.csv",
    params:
        cfg=sections(config, "rig", "joints", "solver"),
    log:
        "logs/verify/{state}.log",
    benchmark:
        "benchmarks/out/verify/{state}.tsv"
    resources:
        mem_mb=3000,
    script:
        "workflow/scripts/verify.py"


rule tables:
    input:
        verify=expand(f"{R}/identify/{{state}}/verify.csv", state=STATES),
        paper="data/paper/paper_tables.csv",
    output:
        power_off=f"{R}/tables/table2_power_off.csv",
        power_on=f"{R}/tables/table3_power_on.csv",
    params:
        cfg={},
    log:
        "logs/tables.log",
    script:
        "workflow/scripts/tables.py"


include: "workflow/rules/report.smk"
include: "workflow/rules/diagnosis.smk"
