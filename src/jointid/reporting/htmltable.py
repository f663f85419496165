"""HTML tables of the report page that fit a 1280 px screen.

* :func:`html_table` - a frame as an HTML table (pandas Styler), at most :data:`MAX_COLUMNS` columns
  wide: a wider frame is shown as several tables that repeat its key columns;
* :func:`notes` - long text that belongs under a table, as a list of notes.
"""

from __future__ import annotations

import html
import math

import pandas as pd

__all__ = ["MAX_COLUMNS", "esc", "fmt", "html_table", "notes", "reset_ids"]

MAX_COLUMNS = 8
"""The widest table on the page (columns)."""

_TABLE_IDS = [0]  # tables on the page so far: each gets its own id (Styler's uuid)


def reset_ids() -> None:
    """Number the tables of a new page from 0 again."""
    _TABLE_IDS[0] = 0


def esc(x) -> str:
    """``x`` as escaped HTML text."""
    return html.escape(str(x))


def fmt(v, spec: str) -> str:
    """``v`` formatted by ``spec``; missing and non-finite values as "–"."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)) or (not isinstance(v, str) and pd.isna(v)):
        return "–"
    return format(v, spec) if spec else str(v)


def notes(items, cls: str = "note") -> str:
    """``items`` (plain text) as a list of notes under a table; empty when there are none."""
    items = [i for i in items if i]
    return f"<ul class='{cls}'>{''.join(f'<li>{esc(i)}</li>' for i in items)}</ul>" if items else ""


def _one_table(df: pd.DataFrame, formats: dict, headers: dict, text_cols) -> str:
    cells = df.rename(columns=headers)
    names = [headers.get(c, c) for c in df.columns]
    text = [headers.get(c, c) for c in df.columns if c in text_cols]
    fm = {headers.get(c, c): (lambda v, spec=formats.get(c, ""): esc(fmt(v, spec))) for c in df.columns}
    classes = pd.DataFrame([["t" if c in text else "" for c in names]] * len(cells), columns=names,
                           index=cells.index)
    uid = f"t{_TABLE_IDS[0]}"
    _TABLE_IDS[0] += 1
    st = (cells.style.format(fm).format_index(escape="html", axis=1).hide(axis="index").set_uuid(uid)
          .set_td_classes(classes)
          .set_table_styles({c: [{"selector": "th", "props": "text-align:left"}] for c in text}, overwrite=False))
    return st.to_html()


def html_table(df: pd.DataFrame, formats: dict[str, str] | None = None, headers: dict[str, str] | None = None,
               text_cols=(), keys: int = 1) -> str:
    """``df`` as an HTML table (pandas Styler): cells formatted by ``formats`` (format specs; missing
    and non-finite values as "–"), columns renamed by ``headers``, ``text_cols`` left-aligned.

    A frame wider than :data:`MAX_COLUMNS` is shown as several tables, each repeating the first
    ``keys`` columns (the row labels) before the next columns.
    """
    formats, headers = formats or {}, headers or {}
    cols = list(df.columns)
    if len(cols) <= MAX_COLUMNS:
        return _one_table(df, formats, headers, text_cols)
    head, rest = cols[:keys], cols[keys:]
    step = MAX_COLUMNS - len(head)
    return "".join(_one_table(df[head + rest[i:i + step]], formats, headers, text_cols)
                   for i in range(0, len(rest), step))
