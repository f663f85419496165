"""Snakemake adapter: modal solve at one DOE point (full FE solve, or the ROM with solver.method: rom)."""
from jointid.config.typed import ModelSpec
from jointid.stages.runner import run_script
from jointid.stages import doe, modal


def _modal(cfg, inp, out):
    """The point's modes; its parameters from the rule's params, else from its sample sheet (zoomed DOE)."""
    spec = ModelSpec.from_config(cfg)
    theta = getattr(snakemake.params, "theta", None)
    theta = dict(theta) if theta else doe.sheet_theta(inp.sheet, snakemake.wildcards.point, spec.joints.names)
    modal.run_modal(spec, inp.matrices, theta, out.modes, rom=inp.get("rom"))


run_script(snakemake, _modal)
