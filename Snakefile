# jointid workflow: joint-surface identification by FE model updating (see README.md).
#
# Path convention: results/<stage>/..., logs/<rule>/..., benchmarks/out/<rule>/...; a study with a
# run.name writes under results/<name>/, logs/<name>/ and benchmarks/out/<name>/ instead (run_folders).
# Config reaches every rule through `params: cfg=` holding only the parts that rule uses (whole
# sections, or single keys such as harmonic.band_Hz, or one state), so a changed value reruns exactly
# the stages that depend on it.  Rules with nothing of their own (gather_modal, tables, table1) get
# the union of their upstream rules' parts: it reruns nothing extra and is what their provenance
# sidecars (<output>.provenance.json) hash.
#
# Every job is single-threaded (parallelism comes from the DOE fan-out): Snakemake sets the BLAS
# thread variables of a job to its `threads`; the defaults below cover this process and anything it
# starts otherwise.  Light rules run in the main process on a cluster (`localrules`).
# Jobs inherit a fixed PYTHONHASHSEED: the order of a Python set of strings then no longer changes
# from process to process, so a sum taken in that order (e.g. in the diagnosis) is bit-reproducible.

import os
import re

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported below
os.environ.setdefault("PYTHONHASHSEED", "0")

from jointid.config.datasets import dataset_folder
from jointid.config.options import DoeOptions
from jointid.config.snakefile import mesh_inputs, mesh_keys, merged, modal_keys, paper_input, run_folders, sections, validated
from jointid.reporting.provenance import pin_config_state
from jointid.config import rule_keys as keys  # the rules' config keys (light: no numerical module is loaded)
from jointid.stages import doe
from jointid.stages.tables import PAPER_TABLES

configfile: "config.yaml"
config = validated(config, ["config.yaml", *workflow.overwrite_configfiles])
# provenance: the config files count as loaded now (an edit during the run changes none of its values)
pin_config_state(["config.yaml", *workflow.overwrite_configfiles])
DOE = DoeOptions.from_config(config)  # the config as typed options at the edge (jointid.config.options)
SHEET = {row["point"]: row for row in doe.doe_rows(DOE)}  # point -> its row of the sample sheet
POINTS = list(SHEET)
STATES = list(config["states"])
R, LOGS, BENCH = run_folders(config)  # results/, logs/, benchmarks/out/ (+ /<run.name> for a named study)

# the config parts each rule uses: its keys in jointid.config.rule_keys (the same tuples as the CONFIG of its
# stage module), or in jointid.config.snakefile (mesh_keys, modal_keys: the mesh without
# mesh.extrapolate_edges; the DOE points solved without the ROM keys); the first DOE without doe.zoom; ...
CFG_MESH = sections(config, *mesh_keys(config))
CFG_DOE = sections(config, *keys.DOE)
CFG_FIT_SURFACE = sections(config, *keys.SURFACE)
CFG_VERIFY = sections(config, *keys.VERIFY)
# mesh.extrapolate_edges: identify (and, with mesh_check.edge_levels, the mesh check) also solves the mesh with one
# and two more edge levels.  It builds them itself, each when its turn comes (about 12 and 16 s): as files they
# took 863 MB of results/ on the default mesh, and a rebuild for one state's rerun reran the other state's chain.


def cfg_identify(state):
    """rule identify: the shared sections, this state's settings and the other states' datasets (the
    measured modes of frequency-only states are paired alike in all states)."""
    return sections(config, *keys.identify(state, STATES))


def state_datasets(wc):
    """Measured datasets of all states (the pairing of frequency-only states is shared)."""
    return sorted({dataset_folder(config, s) for s in STATES})


USE_ROM = config["solver"]["method"] == "rom"
USE_REDUCED = config["solver"]["method"] == "reduced"  # the default: every DOE point in one job (rule modal)
# with method full the modal rule's params leave out the ROM keys (see rule rom below)
CFG_MODAL_RULE = sections(config, *modal_keys(config))
CFG_MODAL_CHAIN = merged(CFG_MESH, CFG_DOE, CFG_MODAL_RULE)
CFG_TABLES_CHAIN = merged(CFG_MODAL_CHAIN, sections(config, "doe.zoom"), CFG_FIT_SURFACE, CFG_VERIFY,
                          *map(cfg_identify, STATES))

EXTRA_TARGETS = []  # rule files included below append their final outputs here
RULE_WILDCARDS = {}  # rule -> wildcard values of its own, where they are fewer than WILDCARD_VALUES's (ARTIFACTS)

# Scheduling on few cores: the run is bound by its total work (both cores busy), so the two long poles go
# first, side by side, and the short jobs fill in around them: the diagnosis and its basis (the longest
# job), then the hypotheses (those with models of their own, then the one job of those on the run's
# model, which ranks with them), and the chain to Tables 1-3 (mesh -> DOE -> surfaces -> identify ->
# verify -> harmonic -> tables) in the gaps.  With the chain first (as before 2026-11-29) the hypotheses'
# one job ran alone at the end with a core idle (benchmark c: 618-641 s against 456 s of 90ed90a).  The
# DOE's one job (rule modal, method reduced) goes beside the basis, before the hypotheses: its chain then
# waits ready for the first core the long poles free.  Started when the diagnosis ended, it ran while the
# hypotheses' ranking (its one consumer then ready) took 11 s, and a core stood idle 9 s for it
# (2026-12-01, make reproduce).  Rule doe, which writes its sheet, has that priority too: a priority is not
# passed on upstream, and at the chain's (lower than the hypotheses') the sheet waited for every hypothesis.
# The mesh check (one job for every state, the longest of the chain's tail: 23 s) starts as soon as both
# states are verified, beside the harmonic jobs: after them it ran 11 s alone with a core idle (2026-12-02,
# 205 s from clean).  The carriage tests and the hypotheses' ranking, which only the report waits for, go
# last, the longer (the carriage tests, 9 s) first: the other way round it ran alone at the end.  The mesh
# goes before all (every other job but the hypotheses with models of their own waits for it); one of those
# starts beside it, on the core that stood idle for the mesh's 6-7 s.
# Priorities only order ready jobs: the results are the same, and a run of one target is unaffected.
PRIORITY_MESH = 31
PRIORITY_LONG = 30
PRIORITY_DOE = 29
PRIORITY_HYPOTHESES = 25
PRIORITY_TABLES = 20
PRIORITY_CHECKS = 10


localrules: all, doe, gather_modal, tables, doe_zoom, gather_zoom


# The default target names every file the run builds (ARTIFACTS, at the end of this file), not only
# the final ones.  Snakemake does not rebuild a missing intermediate file whose consumers are up to
# date: after a kill, or after `jointid results heal` removed a damaged file, it would say "Nothing
# to be done" with a result missing.  Named here, a missing file is rebuilt, and with it everything
# that depends on it.
rule all:
    input:
        f"{R}/tables/table2_power_off.csv",
        f"{R}/tables/table3_power_on.csv",
        lambda wc: EXTRA_TARGETS,  # a function: read after the rule files below have appended
        lambda wc: ARTIFACTS,
    default_target: True


rule mesh:
    input:
        mesh_inputs(config),  # model.kind mesh: the mesh file and the measuring points
    output:
        matrices=f"{R}/model/matrices.npz",
        points=f"{R}/model/measuring_points.csv",
        summary=f"{R}/model/summary.json",
        vtu=f"{R}/model/mesh.vtu",
    params:
        cfg=CFG_MESH,
    log:
        f"{LOGS}/mesh.log",
    benchmark:
        f"{BENCH}/mesh.tsv"
    priority: PRIORITY_MESH
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    script:
        "workflow/scripts/mesh.py"


rule doe:
    output:
        sheet=f"{R}/doe/points.csv",
    params:
        cfg=CFG_DOE,
    log:
        f"{LOGS}/doe.log",
    priority: PRIORITY_DOE  # its sheet lets rule modal start beside the basis (a priority is not passed on upstream)
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    script:
        "workflow/scripts/doe.py"


# solver.method: rom -- one parametric reduced-order model (jointid.identification.rom) over the joint-parameter box,
# built and verified against full solves once; every modal job then evaluates it.  With method full
# (the default) no job asks for it, and the modal rule's params leave out the ROM keys so that the
# full path's jobs, params and results stay exactly those it had before the option existed.
CFG_ROM = sections(config, *keys.ROM)


rule rom:
    input:
        matrices=rules.mesh.output.matrices,
        sheet=rules.doe.output.sheet,
    output:
        rom=f"{R}/rom/rom.npz",
        summary=f"{R}/rom/rom.json",
    params:
        cfg=CFG_ROM,
    log:
        f"{LOGS}/rom.log",
    benchmark:
        f"{BENCH}/rom.tsv"
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    script:
        "workflow/scripts/rom.py"


if USE_REDUCED:

    rule modal:  # every DOE point in one job, on one reduced basis certified point by point
        input:
            matrices=rules.mesh.output.matrices,
            sheet=rules.doe.output.sheet,
        output:
            modes=expand(f"{R}/modal/points/{{point}}.npz", point=POINTS),
        params:
            cfg=CFG_MODAL_RULE,
        log:
            f"{LOGS}/modal/points.log",
        benchmark:
            f"{BENCH}/modal/points.tsv"
        priority: PRIORITY_DOE
        threads: 1
        resources:
            mem_mb=3000,
            runtime=20,
        script:
            "workflow/scripts/modal_points.py"

else:

    rule modal:
        input:
            unpack(lambda wc: {"rom": rules.rom.output.rom} if USE_ROM else {}),
            matrices=rules.mesh.output.matrices,
            sheet=rules.doe.output.sheet,
        output:
            modes=f"{R}/modal/points/{{point}}.npz",
        params:
            cfg=CFG_MODAL_RULE,
            theta=lambda wc: {n: float(SHEET[wc.point][n]) for n in config["joints"]["parameters"]},
        log:
            f"{LOGS}/modal/{{point}}.log",
        benchmark:
            f"{BENCH}/modal/{{point}}.tsv"
        priority: PRIORITY_TABLES
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
        cfg=CFG_MODAL_CHAIN,  # nothing of its own: for the provenance
    log:
        f"{LOGS}/gather_modal.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=1000,
        runtime=2,
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
        cfg=CFG_FIT_SURFACE,
    log:
        f"{LOGS}/fit_surface.log",
    benchmark:
        f"{BENCH}/fit_surface.tsv"
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    script:
        "workflow/scripts/fit_surface.py"


# doe.zoom (sequential response surface, opt-in): the surfaces over the whole bounds give each
# state a first optimum ("scout", surfaces only); a second DOE of the same design is solved in a box
# around those optima (shared by the states: one fan-out), and the surfaces fitted there carry the
# identification.  A quadratic in log-parameters is accurate over a factor ~2, not over decades.
ZOOM = DOE.zoom_enabled
SURFACE = f"{R}/surface/zoom/model.json" if ZOOM else f"{R}/surface/model.json"
SURFACE_DIAGNOSTICS = SURFACE.replace("model.json", "diagnostics.csv")
SURFACE_SHEET = f"{R}/doe/zoom/points.csv" if ZOOM else f"{R}/doe/points.csv"  # the DOE behind SURFACE


def cfg_scout(state):
    """rule scout: what the surface-only identification reads (not the FE solve, not the motor force)."""
    return sections(config, *keys.scout(STATES))


rule scout:
    input:
        surface=rules.fit_surface.output.model,
        points=rules.mesh.output.points,
        summary=rules.mesh.output.summary,
        datasets=state_datasets,
    output:
        params=f"{R}/identify/{{state}}/scout.json",
    params:
        cfg=lambda wc: cfg_scout(wc.state),
        states=STATES,
    log:
        f"{LOGS}/scout/{{state}}.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    script:
        "workflow/scripts/identify.py"


rule doe_zoom:
    input:
        scout=expand(f"{R}/identify/{{state}}/scout.json", state=STATES),
    output:
        sheet=f"{R}/doe/zoom/points.csv",
        box=f"{R}/doe/zoom/box.json",
    params:
        cfg=sections(config, *keys.DOE_ZOOM),
        states=STATES,
    log:
        f"{LOGS}/doe_zoom.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    script:
        "workflow/scripts/doe_zoom.py"


if USE_REDUCED:

    rule modal_zoom:
        input:
            matrices=rules.mesh.output.matrices,
            sheet=rules.doe_zoom.output.sheet,
        output:
            modes=expand(f"{R}/modal/zoom/points/{{point}}.npz", point=POINTS),
        params:
            cfg=CFG_MODAL_RULE,  # the points' parameters come from the zoomed sheet (known at run time)
        log:
            f"{LOGS}/modal_zoom/points.log",
        benchmark:
            f"{BENCH}/modal_zoom/points.tsv"
        priority: PRIORITY_TABLES
        threads: 1
        resources:
            mem_mb=3000,
            runtime=20,
        script:
            "workflow/scripts/modal_points.py"

else:

    rule modal_zoom:
        input:
            unpack(lambda wc: {"rom": rules.rom.output.rom} if USE_ROM else {}),
            matrices=rules.mesh.output.matrices,
            sheet=rules.doe_zoom.output.sheet,
        output:
            modes=f"{R}/modal/zoom/points/{{point}}.npz",
        params:
            cfg=CFG_MODAL_RULE,  # the point's parameters come from the zoomed sheet (known at run time)
        log:
            f"{LOGS}/modal_zoom/{{point}}.log",
        benchmark:
            f"{BENCH}/modal_zoom/{{point}}.tsv"
        priority: PRIORITY_TABLES
        threads: 1
        resources:
            mem_mb=3000,
            runtime=10,
        script:
            "workflow/scripts/modal.py"


rule gather_zoom:
    input:
        sheet=rules.doe_zoom.output.sheet,
        modes=expand(f"{R}/modal/zoom/points/{{point}}.npz", point=POINTS),
    output:
        table=f"{R}/modal/zoom/all.csv",
        arrays=f"{R}/modal/zoom/all.npz",
    params:
        cfg=CFG_MODAL_CHAIN,  # nothing of its own: for the provenance
    log:
        f"{LOGS}/gather_zoom.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=1000,
        runtime=2,
    script:
        "workflow/scripts/gather.py"


rule fit_zoom:
    input:
        sheet=rules.doe_zoom.output.sheet,
        arrays=rules.gather_zoom.output.arrays,
        box=rules.doe_zoom.output.box,
    output:
        model=f"{R}/surface/zoom/model.json",
        diagnostics=f"{R}/surface/zoom/diagnostics.csv",
    params:
        cfg=CFG_FIT_SURFACE,
    log:
        f"{LOGS}/fit_zoom.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    script:
        "workflow/scripts/fit_surface.py"


rule identify:
    input:
        unpack(lambda wc: {"rom": rules.rom.output.rom} if USE_ROM else {}),  # the polish runs on the ROM
        surface=SURFACE,
        points=rules.mesh.output.points,
        summary=rules.mesh.output.summary,
        matrices=rules.mesh.output.matrices,
        datasets=state_datasets,
    output:
        params=f"{R}/identify/{{state}}/params.json",
    params:
        cfg=lambda wc: cfg_identify(wc.state),
        states=STATES,
    log:
        f"{LOGS}/identify/{{state}}.log",
    benchmark:
        f"{BENCH}/identify/{{state}}.tsv"
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=5000,  # 3.4-4.1 GB measured with mesh.extrapolate_edges (the largest edge level's factorisation)
        runtime=20,
    script:
        "workflow/scripts/identify.py"


rule verify:
    input:
        params=rules.identify.output.params,
        surface=SURFACE,
        matrices=rules.mesh.output.matrices,
    output:
        table=f"{R}/identify/{{state}}/verify.csv",
        unpaired=f"{R}/identify/{{state}}/unpaired_visible.csv",
        tied=f"{R}/identify/{{state}}/tied_pairings.csv",
        certificate=f"{R}/identify/{{state}}/certificate.json",  # residual + Sturm count of the full solve
        modes=f"{R}/identify/{{state}}/optimum_modes.npz",  # what the mesh check needs of that solve (20 kB)
    params:
        cfg=CFG_VERIFY,
    log:
        f"{LOGS}/verify/{{state}}.log",
    benchmark:
        f"{BENCH}/verify/{{state}}.tsv"
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=3000,  # one solve and its Sturm count (the edge factors come from identify)
        runtime=10,
    script:
        "workflow/scripts/verify.py"


rule tables:
    input:
        verify=expand(f"{R}/identify/{{state}}/verify.csv", state=STATES),
        unpaired=expand(f"{R}/identify/{{state}}/unpaired_visible.csv", state=STATES),
        paper=paper_input(config, PAPER_TABLES),
    output:
        power_off=f"{R}/tables/table2_power_off.csv",
        unpaired=f"{R}/tables/unpaired_visible.csv",
        power_on=f"{R}/tables/table3_power_on.csv",
        power_off_md=f"{R}/tables/table2_power_off.md",
        power_on_md=f"{R}/tables/table3_power_on.md",
    params:
        cfg=CFG_TABLES_CHAIN,  # nothing of its own: for the provenance
    log:
        f"{LOGS}/tables.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    script:
        "workflow/scripts/tables.py"


include: "workflow/rules/rigidity.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/basis.smk"
include: "workflow/rules/diagnosis.smk"
include: "workflow/rules/meshcheck.smk"
include: "workflow/rules/hypotheses.smk"
include: "workflow/rules/ema.smk"


# Every output of every rule the default run uses, over the run's wildcard values (see rule all).
# ON_DEMAND: rules that the default run does not use with this configuration.
ON_DEMAND = {"all", "current"} | (set() if USE_ROM else {"rom"}) \
    | (set() if ZOOM else {"scout", "doe_zoom", "modal_zoom", "gather_zoom", "fit_zoom"}) \
    | (set() if config["model"]["kind"] == "rig" else {"carriage_rigidity"})
WILDCARD_VALUES = {"state": STATES, "point": POINTS, "dataset": list(DIAG_DATASETS), "name": list(HYPOTHESES),
                   "source": list(EMA_SOURCES)}
ARTIFACTS = sorted({f for r in workflow.rules if r.name not in ON_DEMAND for pattern in r.output
                    for f in expand(re.sub(r"\{(\w+),[^{}]*\}", r"{\1}", str(pattern)),
                                    **{**WILDCARD_VALUES, **RULE_WILDCARDS.get(r.name, {})})})
