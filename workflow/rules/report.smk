# Report stage: harmonic response per state -> Table 1 -> one self-contained HTML page.
#   results/harmonic/{state}/{frf.csv, dynamic_stiffness.json, modes.npz, drive_points.npz}
#   results/harmonic/{state}/{frf_compare.csv, frf_measured_stiffness.json, frf_overlay_measured.png}: measured
#     FRFs against the model's (jointid.stages.frf_compare); without frf.csv they say "no measured FRF"
#   results/tables/table1_dynamic_stiffness.{csv,md}, table1_ranges.csv, table1_cases.csv, table1_pairings.csv
#   results/tables/joint_damping_states.json: the identified joint damping of the states compared
#     (jointid.stages.damping_states); {"available": false, ...} on frequency-only data
#   results/report/index.html (+ figures/*.png, wrapped for `snakemake --report report.html`)
# Captions of the figures: workflow/report/*.rst (paths relative to this file).

from jointid.config.datasets import dataset_folder as _dataset_folder
from jointid.config.datasets import registered_datasets as _registered_datasets
from jointid.config import rule_keys as keys
from jointid.config.hypotheses import hypothesis_names as _hypothesis_names

FIGURES = ["frf", "errors", "parameters", "surface", "doe", "mode_shapes"]


def cfg_harmonic(state):
    """rule harmonic: the shared sections and this state's settings only."""
    return sections(config, *keys.harmonic(state))


CFG_TABLE1_CHAIN = merged(CFG_TABLES_CHAIN, *map(cfg_harmonic, STATES))
# rule joint_damping_states reads the params.json of the states: nothing of its own, for the provenance
CFG_DAMPING_STATES = merged(CFG_MODAL_CHAIN, sections(config, "doe.zoom"), CFG_FIT_SURFACE, *map(cfg_identify, STATES))

localrules: table1, joint_damping_states


rule harmonic:
    input:
        params=rules.identify.output.params,
        matrices=rules.mesh.output.matrices,
        verify=rules.verify.output.table,
        tied=rules.verify.output.tied,
        dataset=lambda wc: _dataset_folder(config, wc.state),
    output:
        frf=f"{R}/harmonic/{{state}}/frf.csv",
        stiffness=f"{R}/harmonic/{{state}}/dynamic_stiffness.json",
        modes=f"{R}/harmonic/{{state}}/modes.npz",
        points=f"{R}/harmonic/{{state}}/drive_points.npz",
        modes_vtu=f"{R}/model/modes_{{state}}.vtu",  # ParaView: Warp By Vector
        modes_uff=f"{R}/model/modes_{{state}}.uff",  # test software: UFF 164 + 15 + 55
        # measured FRFs against the model's; written, saying so, when the dataset has no frf.csv
        frf_compare=f"{R}/harmonic/{{state}}/frf_compare.csv",
        frf_measured_stiffness=f"{R}/harmonic/{{state}}/frf_measured_stiffness.json",
        frf_overlay=f"{R}/harmonic/{{state}}/frf_overlay_measured.png",
    params:
        cfg=lambda wc: cfg_harmonic(wc.state),
    log:
        f"{LOGS}/harmonic/{{state}}.log",
    benchmark:
        f"{BENCH}/harmonic/{{state}}.tsv"
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    script:
        "../scripts/harmonic.py"


rule table1:
    input:
        stiffness=expand(f"{R}/harmonic/{{state}}/dynamic_stiffness.json", state=STATES),
        points=expand(f"{R}/harmonic/{{state}}/drive_points.npz", state=STATES),
        paper=paper_input(config, "data/paper/paper_table1.csv"),
    output:
        csv=report(f"{R}/tables/table1_dynamic_stiffness.csv", caption="../report/table1.rst",
                   category="Tables"),
        md=f"{R}/tables/table1_dynamic_stiffness.md",
        ranges=f"{R}/tables/table1_ranges.csv",
        cases=f"{R}/tables/table1_cases.csv",
        pairings=f"{R}/tables/table1_pairings.csv",  # Table 1 under the chosen and every exactly tied pairing
    params:
        cfg=CFG_TABLE1_CHAIN,  # harmonic.band_Hz / n_freq for the ranges; the rest for the provenance
    log:
        f"{LOGS}/table1.log",
    priority: PRIORITY_TABLES
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    script:
        "../scripts/table1.py"


rule joint_damping_states:
    input:
        params=expand(f"{R}/identify/{{state}}/params.json", state=STATES),
    output:
        json=f"{R}/tables/joint_damping_states.json",
    params:
        cfg=CFG_DAMPING_STATES,  # nothing of its own: for the provenance
    log:
        f"{LOGS}/joint_damping_states.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    script:
        "../scripts/damping_states.py"


rule report:
    input:
        table1=rules.table1.output.csv,
        table1_ranges=rules.table1.output.ranges,
        table2=rules.tables.output.power_off,
        table3=rules.tables.output.power_on,
        paper_table1=paper_input(config, "data/paper/paper_table1.csv"),
        verify=expand(f"{R}/identify/{{state}}/verify.csv", state=STATES),
        params=expand(f"{R}/identify/{{state}}/params.json", state=STATES),
        rigidity=(expand(f"{R}/identify/{{state}}/carriage_rigidity.json", state=STATES)
                  if config["model"]["kind"] == "rig" else []),  # the rig's carriage on its rail
        frf=expand(f"{R}/harmonic/{{state}}/frf.csv", state=STATES),
        frf_compare=expand(f"{R}/harmonic/{{state}}/frf_compare.csv", state=STATES),  # read beside frf.csv
        damping_states=rules.joint_damping_states.output.json,
        stiffness=expand(f"{R}/harmonic/{{state}}/dynamic_stiffness.json", state=STATES),
        modes=expand(f"{R}/harmonic/{{state}}/modes.npz", state=STATES),
        diagnostics=SURFACE_DIAGNOSTICS,  # the surfaces that carried the identification
        sheet=SURFACE_SHEET,
        points=rules.mesh.output.points,
        mesh_check=expand(f"{R}/mesh_check/{{state}}.json", state=STATES) if config["mesh_check"]["enabled"] else [],
        hypotheses=f"{R}/hypotheses/ranking.csv" if _hypothesis_names(config) else [],  # rules/hypotheses.smk
        hypothesis_fits=expand(f"{R}/hypotheses/{{name}}/fit.json", name=_hypothesis_names(config)),
        # the summary card's verdict (rules/diagnosis.smk; verdict.json and combinations.csv are read beside)
        diagnosis=expand(f"{R}/diagnosis/{{dataset}}/ranking.csv", dataset=list(_registered_datasets(config))),
    output:
        html=report(f"{R}/report/index.html", caption="../report/index.rst", category="Report"),
        frf=report(f"{R}/report/figures/frf.png", caption="../report/frf.rst", category="Harmonic response"),
        errors=report(f"{R}/report/figures/errors.png", caption="../report/errors.rst",
                      category="Natural frequencies"),
        parameters=report(f"{R}/report/figures/parameters.png", caption="../report/parameters.rst",
                          category="Identification"),
        surface=report(f"{R}/report/figures/surface.png", caption="../report/surface.rst",
                       category="Identification"),
        doe=report(f"{R}/report/figures/doe.png", caption="../report/doe.rst", category="Identification"),
        mode_shapes=report(f"{R}/report/figures/mode_shapes.png", caption="../report/mode_shapes.rst",
                           category="Natural frequencies"),
    params:
        cfg=config,
    log:
        f"{LOGS}/report.log",
    benchmark:
        f"{BENCH}/report.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=10,
    script:
        "../scripts/report.py"


EXTRA_TARGETS += [
    f"{R}/tables/table1_dynamic_stiffness.csv",
    f"{R}/tables/table1_dynamic_stiffness.md",
    f"{R}/tables/table1_ranges.csv",
    f"{R}/tables/joint_damping_states.json",
    f"{R}/report/index.html",
]
