"""Snakemake adapter: modal solve at one DOE point (full FE solve, or the ROM with solver.method: rom)."""
from jointid.stages.runner import run_script
from jointid.stages import doe, modal


def _theta(cfg, inp):
    """The point's parameters: from the rule's params, else from its sample sheet (zoomed DOE)."""
    given = getattr(snakemake.params, "theta", None)
    if given:
        return dict(given)
    return doe.sheet_theta(inp.sheet, snakemake.wildcards.point, doe.parameter_names(cfg))


run_script(snakemake, lambda cfg, inp, out: modal.run_modal(
    cfg, inp.matrices, _theta(cfg, inp), out.modes, rom=inp.get("rom")))
