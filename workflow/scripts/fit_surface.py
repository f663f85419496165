"""Snakemake adapter: track modes through the DOE and fit the response surfaces."""
from jointid.config.options import SurfaceOptions
from jointid.stages.runner import run_script
from jointid.stages import surface

run_script(snakemake, lambda cfg, inp, out: surface.run_fit_surface(
    SurfaceOptions.from_config(cfg), inp.sheet, inp.arrays, out.model, out.diagnostics, box_json=inp.get("box")), provenance=True)
