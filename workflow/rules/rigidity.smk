# Carriage rigidity: each state's identified joint springs in a catalogue-style test of one carriage
# on its rail (jointid.response.carriage), the number to hold against a guide catalogue.
#   results/identify/{state}/carriage_rigidity.json (per direction: springs, parts, assembly, interval)

from jointid.config import rule_keys as keys

CFG_RIGIDITY = sections(config, *keys.CARRIAGE)


rule carriage_rigidity:  # every state in one job: the test model is assembled once
    input:
        params=expand(rules.identify.output.params, state=STATES),
    output:
        json=expand(f"{R}/identify/{{state}}/carriage_rigidity.json", state=STATES),
    params:
        cfg=CFG_RIGIDITY,
        states=STATES,
    log:
        f"{LOGS}/carriage_rigidity.log",
    benchmark:
        f"{BENCH}/carriage_rigidity.tsv"
    priority: PRIORITY_CHECKS + 1  # before the hypotheses' ranking: at the end it ran 9 s alone (see the Snakefile)
    threads: 1
    resources:
        mem_mb=2000,  # 1.4-1.5 GB measured (the 41k-DOF factorisations of the default 6 mm cells)
        runtime=5,
    script:
        "../scripts/carriage_rigidity.py"


if config["model"]["kind"] == "rig":  # a catalogue test of the rig's carriage on its rail
    EXTRA_TARGETS.extend(expand(f"{R}/identify/{{state}}/carriage_rigidity.json", state=STATES))
