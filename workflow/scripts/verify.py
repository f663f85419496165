"""Snakemake adapter: full FE re-solve at the identified parameters."""
from jointid.config.typed import ModelSpec
from jointid.stages.runner import run_script
from jointid.stages import verify

run_script(snakemake, lambda cfg, inp, out: verify.run_verify(
    ModelSpec.from_config(cfg), snakemake.wildcards.state, inp.params, inp.surface, inp.matrices, out.table,
    edge_matrices=list(inp.get("edges") or []), unpaired_csv=out.unpaired,
    tied_csv=out.tied, certificate_json=out.certificate, modes_npz=out.modes), provenance=True)
