"""The files of one diagnosis: the result tables (CSV), ``verdict.json`` and ``index.html``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jointid import io
from jointid.diagnosis.judging import supported_order
from jointid.diagnosis.loop import Diagnosis
from jointid.reporting.diagnosis_page import html_page


def write_outputs(res: Diagnosis, out_dir, dataset: str, run: dict, figs: dict | None = None) -> None:
    """Write ranking.csv, ladder.csv, compare.csv, current.csv, parameters.csv, drift.csv,
    shape_residuals.csv, point_residuals.csv, mac_<state>.csv, combinations.csv, next_measurements.csv,
    preload_curve.csv, verdict.json and index.html (``figs``: the page's figures when made already,
    :func:`jointid.reporting.diagnosis_page.html_page`)."""
    out = Path(out_dir)
    page = html_page(res, dataset, run, figs)  # figures first: a failure there leaves no partial set behind
    io.write_csv(res.ranking, out / "ranking.csv")
    io.write_csv(res.ladder, out / "ladder.csv")
    io.write_csv(res.compare, out / "compare.csv")
    io.write_csv(res.current, out / "current.csv")
    io.write_csv(res.parameters if res.parameters is not None else pd.DataFrame(), out / "parameters.csv")
    io.write_csv(res.drift, out / "drift.csv")
    io.write_csv(res.shape_residuals, out / "shape_residuals.csv")
    io.write_csv(res.point_residuals, out / "point_residuals.csv")
    for state, M in res.mac.items():
        df = pd.DataFrame(M, columns=[f"model_{j + 1}" for j in range(M.shape[1])])
        df.insert(0, "measured_mode", np.arange(1, M.shape[0] + 1))
        io.write_csv(df, out / f"mac_{state}.csv")
    io.write_csv(res.combinations, out / "combinations.csv")
    io.write_csv(res.next_measurements, out / "next_measurements.csv")
    io.write_csv(res.preload_curve, out / "preload_curve.csv")
    io.write_json(out / "verdict.json", verdict_record(res, dataset, run))
    io.write_text(out / "index.html", page)


def supported_names(res: Diagnosis) -> list[str]:
    """The refitted candidates and pairs the data support against the current model, best first (a pair
    after its own single when they tie: :func:`jointid.diagnosis.judging.parsimonious_order`)."""
    return supported_order(res.ranking, res.combinations)


def verdict_record(res: Diagnosis, dataset: str, run: dict) -> dict:
    """The content of ``verdict.json``: the verdict, its short form, the effects it names (several
    when the data cannot tell them apart or a combination is needed), what the data identify, the
    absorbed candidates, the measurements that would decide and the notes."""
    short = res.explained_by
    if short in ("none needed", "unexplained"):
        named, kind = [], short
    elif " or " in short:
        named, kind = short.split(" or "), "indistinguishable"
    elif "+" in short:
        named, kind = short.split("+"), "combination"
    else:
        named, kind = [short], "single"
    return {"dataset": dataset, "verdict": res.verdict, "explained_by": short, "kind": kind, "effects": named,
            "model_error": res.model_error.record(), "model_error_text": res.model_error.sentence(),
            "supported": supported_names(res),
            "identifiable": res.identifiable, "absorbed": res.absorbed,
            "next_measurements": res.next_measurements.to_dict(orient="records"),
            "notes": res.notes, "run": run, "timing_s": res.timing_s}
