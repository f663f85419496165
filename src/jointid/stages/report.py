"""Rule ``report``: the self-contained HTML report of a run (:mod:`jointid.reporting.page`) and its
figures as PNG files (for ``snakemake --report``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.options import ReportOptions


def _as_list(x) -> list:
    return [x] if isinstance(x, (str, Path)) else list(x)


def load_inputs(inputs: dict) -> dict:
    """The report's data: tables and frames read from the paths of ``inputs`` (see :func:`run_report`);
    per-state files keyed by the state (their parent folder's name); ``table1_problems``: those of
    :func:`jointid.reporting.checks.check_table1` (shown on the page)."""
    import numpy as np
    import pandas as pd

    from jointid.identification.record import IdentificationRecord
    from jointid.reporting.checks import check_table1
    from jointid.stages.tables import PAPER_TABLE1_COLUMNS, read_paper

    by_state = lambda key, reader: {Path(p).parent.name: reader(p) for p in _as_list(inputs[key])}  # noqa: E731
    return {
        "table1": io.read_csv(inputs["table1"]),
        "table1_ranges": io.read_csv(inputs["table1_ranges"]) if inputs.get("table1_ranges") else None,
        "tables": {"power_off": io.read_csv(inputs["table2"]), "power_on": io.read_csv(inputs["table3"])},
        "verify": by_state("verify", io.read_csv),
        "params": by_state("params", IdentificationRecord.read),
        "frf": by_state("frf", io.read_csv),
        "stiffness": by_state("stiffness", io.read_json),
        "modes": by_state("modes", lambda p: dict(io.load_npz(p))),
        "diagnostics": io.read_csv(inputs["diagnostics"]),
        "sheet": io.read_csv(inputs["sheet"]),
        "points": io.read_csv(inputs["points"]),
        "paper_table1": read_paper(inputs.get("paper_table1") or None, PAPER_TABLE1_COLUMNS),
        "mesh_check": {d["state"]: d for d in map(io.read_json, _as_list(inputs.get("mesh_check") or []))},
        "rigidity": {d["state"]: d for d in map(io.read_json, _as_list(inputs.get("rigidity") or []))},
        "table1_problems": check_table1(inputs["table1"]),
        "hypotheses": _hypotheses(inputs),
        "diagnosis": _diagnosis(inputs),
        "frf_measured": _frf_measured(inputs),
        "joint_damping_states": io.read_json(inputs["damping_states"]) if inputs.get("damping_states") else None,
    }


def _frf_measured(inputs: dict):
    """Measured against model FRFs (:func:`jointid.reporting.frf_section.load_frf_section`), read beside
    each state's harmonic results; None when the dataset has no ``frf.csv``."""
    from jointid.reporting.frf_section import load_frf_section

    paths = [Path(p) for p in _as_list(inputs.get("frf") or [])]
    if not paths:
        return None
    return load_frf_section(paths[0].parent.parent, [p.parent.name for p in paths])


def _csv_or_none(path: Path):
    import pandas as pd

    return io.read_csv(path) if path.exists() and path.stat().st_size > 1 else None


def _diagnosis(inputs: dict) -> dict:
    """Per diagnosed dataset (its folder's name): ``verdict`` (verdict.json), ``ranking`` and
    ``combinations`` (the CSVs beside it) and ``page`` (the path of its index.html, under this study's
    results folder); empty when the run's report has no diagnosis."""
    import pandas as pd

    out = {}
    for p in map(Path, _as_list(inputs.get("diagnosis") or [])):
        if p.with_name("verdict.json").exists():
            ranking = _csv_or_none(p)
            out[p.parent.name] = {"verdict": io.read_json(p.with_name("verdict.json")),
                                  "ranking": pd.DataFrame() if ranking is None else ranking,
                                  "combinations": _csv_or_none(p.with_name("combinations.csv")),
                                  "page": p.with_name("index.html").as_posix()}
    return out


def _hypotheses(inputs: dict):
    """The hypotheses' ranking, records, spread, reconstruction ranges and next measurements (None when
    the run has no hypotheses)."""
    import pandas as pd

    if not inputs.get("hypotheses"):
        return None
    ranking = io.read_csv(inputs["hypotheses"])
    records = {r["hypothesis"]: r for r in map(io.read_json, _as_list(inputs.get("hypothesis_fits") or []))}
    def beside(name):
        path = Path(inputs["hypotheses"]).with_name(name)
        return io.read_csv(path) if path.exists() and path.stat().st_size > 1 else None

    return {"ranking": ranking, "records": records, "spread": beside("spread.csv"),
            "ranges": beside("reconstruction.csv"), "next": beside("next_measurements.csv")}


def run_report(opts: ReportOptions, inputs: dict, outputs: dict, workdir=".") -> str:
    """The ``report`` workflow stage.

    Parameters
    ----------
    opts : ReportOptions
        Of the whole configuration (shown, and hashed): :meth:`jointid.config.options.ReportOptions.from_config`.
    inputs : dict
        Paths: ``table1, table2, table3, paper_table1, diagnostics, sheet, points`` (one each),
        ``table1_ranges`` (optional),
        ``verify, params, frf, stiffness, modes`` (one per state; the state is the parent folder name)
        and optionally ``mesh_check`` (one JSON per state, from the rule mesh_check), ``rigidity``
        (one JSON per state, from the rule carriage_rigidity) and ``diagnosis`` (one ranking.csv per
        diagnosed dataset, rule diagnose; its verdict.json is read beside it) and ``damping_states``
        (``joint_damping_states.json``, rule joint_damping_states: a section when a state's joint damping is
        identified).
    outputs : dict
        ``html`` and one PNG path per figure (``frf, errors, parameters, surface, doe, mode_shapes``);
        figures without a path are only embedded.
    workdir : path-like
        The workflow's folder (its git commit is shown).

    Returns
    -------
    str
        The HTML page.
    """
    from jointid.reporting.page import build_html, report_figures
    from jointid.reporting.provenance import run_record

    data = load_inputs(inputs)
    figs = report_figures(opts, data)
    for name, png in figs.items():
        if outputs.get(name):
            with io.atomic_path(outputs[name]) as tmp:
                tmp.write_bytes(png)
    page = build_html(opts, data, figs, run_record(opts.stamp, workdir))
    io.write_text(outputs["html"], page)
    log(f"report: {outputs['html']} ({len(page) / 1e6:.1f} MB, {len(figs)} figures)")
    return page
