"""Snakemake adapter: drive-point FRF and dynamic stiffness of one state at its identified parameters."""
from jointid.config.options import HarmonicOptions
from jointid.stages.runner import run_script
from jointid.stages import harmonic

run_script(snakemake, lambda cfg, inp, out: harmonic.run_harmonic(
    HarmonicOptions.from_config(cfg, snakemake.wildcards.state), snakemake.wildcards.state, inp.params, inp.matrices, out.frf, out.stiffness,
    out_modes=out.modes, verify_csv=inp.verify, out_points=out.points, out_vtu=out.modes_vtu,
    out_uff=out.modes_uff, tied_csv=inp.tied), provenance=True)
