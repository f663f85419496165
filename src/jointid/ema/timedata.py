"""H1 FRFs from hammer time histories, with coherence, the windows stated and low-coherence bands flagged.

Input: a CSV with columns ``reference, hit, time_s, force_N`` and one column per response DOF named
``<point>:<direction>_m_per_s2`` (acceleration, m/s^2); one block of rows per hit, time from 0 at an even
step.  Each hit is windowed: the force by a **force window** (1 until twice the time from the peak to
where the force first falls below 1 % of its peak, 0 after), force and response both by an
**exponential window** ``exp(-t / tau)`` falling to ``exp_end`` (default 1 %) at the record's end.
``H1 = G_fx / G_ff`` over the hits, coherence ``|G_fx|^2 / (G_ff G_xx)``, receptance ``H1 / -(w^2)``.
The exponential window adds ``1 / tau`` to every pole's decay rate; the EMA subtracts it
(:attr:`jointid.ema.frfs.FrfSet.exp_decay_per_s`).  Lines below ``coherence_min`` are flagged; an FRF
with more than ``max_low_coherence_fraction`` of its lines flagged is an error.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jointid.data.validate import DIRECTIONS
from jointid.ema.frfs import FrfSet
from jointid.errors import DataError

__all__ = ["read_time_csv", "h1_frfs", "force_window", "low_coherence_bands", "RESPONSE_SUFFIX"]

RESPONSE_SUFFIX = "_m_per_s2"
NYQUIST_SHARE = 0.8
"""Lines up to this share of the Nyquist frequency are kept (above it the anti-alias filter acts)."""


def read_time_csv(path) -> pd.DataFrame:
    """The time-history table (columns checked; one line per problem)."""
    path = Path(path)
    try:
        df = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot read as CSV ({exc}) — save it as comma-separated UTF-8") from exc
    problems = [f"{path}:1: missing column {c!r} — the columns are reference, hit, time_s, force_N and "
                f"<point>:<direction>{RESPONSE_SUFFIX} per response" for c in ("reference", "hit", "time_s", "force_N")
                if c not in df.columns]
    responses = [c for c in df.columns if c.endswith(RESPONSE_SUFFIX)]
    if not responses:
        problems.append(f"{path}:1: no response column — name each <point>:<direction>{RESPONSE_SUFFIX} "
                        "(acceleration in m/s^2), e.g. T01:y_m_per_s2")
    for c in responses:
        label = c[: -len(RESPONSE_SUFFIX)]
        if label.count(":") != 1 or label.split(":")[1] not in DIRECTIONS:
            problems.append(f"{path}:1: response column {c!r} is not <point>:<direction>{RESPONSE_SUFFIX} — "
                            "write e.g. T01:y_m_per_s2")
    if problems:
        raise DataError(problems)
    return df


def force_window(t, force) -> np.ndarray:
    """1 until twice the time from the force peak to where it first falls below 1 % of the peak, then 0."""
    k = int(np.argmax(np.abs(force)))
    below = np.flatnonzero(np.abs(force[k:]) < 0.01 * abs(force[k]))
    end = t[k] + 2 * (t[k + below[0]] - t[k]) if below.size else t[-1]
    return (t <= end).astype(float)


def low_coherence_bands(freq, coh, threshold) -> list[tuple[float, float]]:
    """Contiguous frequency ranges (Hz) where ``coh`` is below ``threshold``."""
    low = coh < threshold
    out, start = [], None
    for f, bad in zip(freq, low):
        if bad and start is None:
            start = f
        if not bad and start is not None:
            out.append((start, prev))
            start = None
        prev = f
    if start is not None:
        out.append((start, freq[-1]))
    return out


def h1_frfs(table: pd.DataFrame, *, state: str = "measured", source: str = "time data", coherence_min: float = 0.9,
            max_low_fraction: float = 0.2, exp_end: float = 0.01, log=print) -> FrfSet:
    # many parameters: the table, the state name, its source, the coherence rule, the window end, log
    """H1 receptances of every response for each reference of ``table`` (:func:`read_time_csv`)."""
    responses = [c for c in table.columns if c.endswith(RESPONSE_SUFFIX)]
    problems, blocks, rows, coherence, grid, decay = [], [], [], [], None, None
    for ref, rg in table.groupby("reference", sort=False):
        ref = str(ref)
        if ref.count(":") != 1 or ref.split(":")[1] not in DIRECTIONS:
            problems.append(f"{source}: reference {ref!r} is not <point>:<direction> — write e.g. T05:y")
            continue
        hits = [g.sort_values("time_s") for _, g in rg.groupby("hit", sort=False)]
        if len(hits) < 2:
            problems.append(f"{source}: reference {ref}: {len(hits)} hit — coherence needs two hits or more; "
                            "record several hits per reference")
            continue
        t = hits[0]["time_s"].to_numpy(float)
        dt = np.diff(t)
        if t.size < 16 or np.any(dt <= 0) or np.ptp(dt) > 1e-6 * dt.mean() or any(len(h) != len(t) for h in hits):
            problems.append(f"{source}: reference {ref}: time_s is not one even, increasing step of equal length in "
                            "every hit — export each hit on the same sampling grid")
            continue
        tau = (t[-1] - t[0]) / np.log(1 / exp_end)
        we = np.exp(-(t - t[0]) / tau)
        freq = np.fft.rfftfreq(t.size, dt.mean())
        keep = (freq > 0) & (freq <= NYQUIST_SHARE * freq[-1])
        gff, gfx, gxx = 0.0, 0.0, 0.0
        for h in hits:
            f = h["force_N"].to_numpy(float)
            x = h[responses].to_numpy(float)
            F = np.fft.rfft(f * force_window(t, f) * we)
            X = np.fft.rfft(x * we[:, None], axis=0)
            gff = gff + np.abs(F) ** 2
            gfx = gfx + np.conj(F)[:, None] * X
            gxx = gxx + np.abs(X) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            h1 = gfx / gff[:, None]
            coh = np.abs(gfx) ** 2 / (gff[:, None] * gxx)
        if grid is not None and (grid.size != keep.sum() or not np.allclose(grid, freq[keep])):
            problems.append(f"{source}: reference {ref}: other sampling (rate or record length) than the first "
                            "reference — record every reference on the same grid")
            continue
        w = 2 * np.pi * freq[keep]
        blocks.append((h1[keep] / -(w[:, None] ** 2)).T)
        coherence.append(coh[keep].T)
        rp, rd = ref.split(":")
        rows += [(c[: -len(RESPONSE_SUFFIX)].split(":")[0], c[: -len(RESPONSE_SUFFIX)].split(":")[1], rp, rd)
                 for c in responses]
        grid = freq[keep] if grid is None else grid
        decay = 1 / tau
        log(f"reference {ref}: {len(hits)} hits, {t.size} samples at {1 / dt.mean():g} Hz; force window to twice "
            f"the pulse, exponential window to {exp_end:g} at {t[-1]:g} s (adds {1 / tau:.3g} 1/s to every pole's "
            "decay; subtracted)")
    if problems:
        raise DataError(problems)
    H, coh = np.vstack(blocks), np.vstack(coherence)
    frame = pd.DataFrame(rows, columns=["point", "direction", "ref_point", "ref_direction"])
    for i, r in frame.iterrows():
        bands = low_coherence_bands(grid, np.nan_to_num(coh[i]), coherence_min)
        share = float(np.mean(np.nan_to_num(coh[i]) < coherence_min))
        where = f"{r['point']}:{r['direction']} / {r['ref_point']}:{r['ref_direction']}"
        if share > max_low_fraction:
            problems.append(f"{source}: FRF {where}: coherence below {coherence_min:g} on {100 * share:.0f} % of the "
                            f"lines (at most {100 * max_low_fraction:g} % allowed; e.g. {_bands(bands)}) — check the "
                            "sensor and the hammer, and average more hits")
        elif bands:
            log(f"FRF {where}: low coherence (< {coherence_min:g}) flagged in {_bands(bands)}")
    if problems:
        raise DataError(problems)
    return FrfSet(state=state, freq_Hz=grid, H=H, rows=frame, source=source, exp_decay_per_s=float(decay),
                  coherence=coh)


def _bands(bands, shown: int = 3) -> str:
    text = ", ".join(f"{a:.0f}-{b:.0f} Hz" for a, b in bands[:shown])
    return text + (f" and {len(bands) - shown} more" if len(bands) > shown else "")
