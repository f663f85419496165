"""The files of one diagnosis: the result tables (CSV), ``verdict.json`` and ``index.html``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jointid import io
from jointid.diagnosis.loop import Diagnosis
from jointid.diagnosis.page import html_page


def write_outputs(res: Diagnosis, out_dir, dataset: str, run: dict) -> None:
    """Write ranking.csv, ladder.csv, compare.csv, current.csv, parameters.csv, drift.csv,
    shape_residuals.csv, point_residuals.csv, mac_<state>.csv, verdict.json and index.html."""
    out = Path(out_dir)
    page = html_page(res, dataset, run)  # figures first: a failure there leaves no partial set behind
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
    io.write_json(out / "verdict.json", {"dataset": dataset, "verdict": res.verdict, "explained_by": res.explained_by,
                                         "notes": res.notes, "run": run, "timing_s": res.timing_s})
    io.write_text(out / "index.html", page)
