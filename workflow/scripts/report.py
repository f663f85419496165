"""Snakemake adapter: the self-contained HTML report and its figures."""
from jointid.config.options import ReportOptions
from jointid.stages.runner import run_script
from jointid.stages import report

run_script(snakemake, lambda cfg, inp, out: report.run_report(ReportOptions.from_config(cfg), dict(inp.items()), dict(out.items())))
