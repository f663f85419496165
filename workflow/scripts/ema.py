"""Snakemake adapter: one named FRF source -> its EMA dataset folder and report (jointid.stages.ema)."""
from jointid.ema.options import EmaOptions
from jointid.stages.runner import run_script
from jointid.stages import ema

run_script(snakemake, lambda cfg, inp, out: ema.run_ema_stage(EmaOptions.from_section(cfg.get("ema")), inp.source, out.dataset, out.poles),
           provenance=["poles"])
