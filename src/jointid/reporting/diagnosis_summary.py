"""The diagnosis verdict in one sentence, for the summary cards of the diagnosis page and of the report.

:func:`short_verdict` reads the verdict's short form (``explained_by``: ``none needed``, an effect,
``a or b``, ``a+b`` or ``unexplained``) and the judged candidates (the ranking and the pairs). The
whole verdict, one paragraph, is :func:`jointid.diagnosis.verdict.verdict_text`.
"""

from __future__ import annotations

import pandas as pd

from jointid.diagnosis.judging import SUPPORTED

__all__ = ["short_verdict"]


def _best_supported(ranking: pd.DataFrame, combinations: pd.DataFrame | None):
    """The supported single or pair with the lowest ΔQAICc, as (name, row), or None."""
    rows = []
    for df, col in ((ranking, "effect"), (combinations, "effects")):
        if df is not None and len(df) and {"support", "delta_qaicc"} <= set(df.columns):
            ok = df[df["support"].isin(SUPPORTED)]
            rows += [(float(r["delta_qaicc"]), str(r[col]), r) for _, r in ok.iterrows()]
    if not rows:
        return None
    _, name, row = min(rows, key=lambda x: x[0])
    return name, row


def _support_text(name: str, row) -> str:
    removed = row.get("removed_fraction")
    part = "" if removed is None or pd.isna(removed) else f", it removes {100 * float(removed):.0f} % of the misfit"
    return f"{name} ({row['support']} supported: ΔQAICc {float(row['delta_qaicc']):.1f}{part})"


def short_verdict(explained_by: str, ranking: pd.DataFrame, combinations: pd.DataFrame | None = None) -> str:
    """One sentence: which listed effect the model lacks, or that none explains the residual and which
    is best supported."""
    if explained_by == "none needed":
        return "The current model fits within the stated noise; no listed effect is needed."
    if explained_by == "unexplained":
        best = _best_supported(ranking, combinations)
        pairs = " alone or in pairs" if combinations is not None and len(combinations) else ""
        if best is None:
            return f"No listed effect{pairs} explains the residual, and none is supported against the current model."
        return (f"No listed effect{pairs} explains the residual to the noise; the best supported is "
                f"{_support_text(*best)}.")
    if " or " in explained_by:
        return f"The data cannot tell {explained_by} apart: each explains the residual to the noise."
    if "+" in explained_by:
        return f"{' and '.join(explained_by.split('+'))} together explain the residual to the noise; no single effect does."
    return f"{explained_by} explains the residual to the noise."
