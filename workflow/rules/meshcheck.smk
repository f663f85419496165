# Mesh check (mesh_check.enabled, on by default): each state's identified parameters re-solved on a nested
# refinement of the mesh; the first-order change a re-identification there would give.  One job for every
# state: the refined mesh is built once.  The default mesh's solve at those parameters is rule verify's
# (results/identify/{state}/optimum_modes.npz): not solved again.
#   results/mesh_check/{state}.json (parameters: value, refined value, change %, 95 % interval)
#   results/mesh_check/{state}.csv  (every mode: default and refined frequency, change %, MAC)

from jointid.config import rule_keys as keys

CFG_MESH_CHECK = sections(config, *keys.MESH_CHECK)

# a mesh file (model.kind mesh) is solved as it is: no refinement, so no mesh check (refine the file and compare)
if config["mesh_check"]["enabled"] and (config.get("model") or {}).get("kind", "rig") != "mesh":

    rule mesh_check:  # every state in one job: the refined mesh is built once
        input:
            params=expand(rules.identify.output.params, state=STATES),
            verify=expand(rules.verify.output.table, state=STATES),
            # the default mesh's solve at the identified parameters
            modes=expand(rules.verify.output.modes, state=STATES),
            matrices=rules.mesh.output.matrices,
        output:
            json=expand(f"{R}/mesh_check/{{state}}.json", state=STATES),
            csv=expand(f"{R}/mesh_check/{{state}}.csv", state=STATES),
        params:
            cfg=CFG_MESH_CHECK,
            states=STATES,
        log:
            f"{LOGS}/mesh_check.log",
        benchmark:
            f"{BENCH}/mesh_check.tsv"
        priority: PRIORITY_TABLES + 1  # first of the chain's tail, beside the harmonic jobs (see the Snakefile)
        threads: 1
        resources:
            mem_mb=16000,  # 15.5 GB measured with halve: [joint_zone] (7.2 GB with the default [thickness])
            runtime=30,
        script:
            "../scripts/mesh_check.py"

    EXTRA_TARGETS.extend(expand(f"{R}/mesh_check/{{state}}.json", state=STATES))
