"""Physical poles: stable in frequency, damping and shape across model orders, clustered.

A pole of order n is *stable* when the closest pole (in frequency) of the next lower order lies within
``freq_tol_pct`` in frequency and ``damping_tol_pct`` in damping, and the MAC of their LSFD residue
vectors is at least ``mac_min``.  Stable poles are sorted by frequency and chained while neighbours lie
within ``freq_tol_pct``; a chain stable at ``min_stable_orders`` orders or more is one physical pole
(one member per order: the closest to the chain's median frequency).  Its frequency and damping are
the members' medians; their standard deviations are the scatter over orders.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointid.ema.options import EmaOptions
from jointid.ema.poles import PoleChart, lsfd, pole_freq_damping

__all__ = ["ChartPoint", "Cluster", "classify", "select_physical", "mac"]

QUICK_LINES = 600
"""The residues that compare shapes across orders are fitted on at most this many lines."""


def mac(a, b) -> float:
    """Modal assurance criterion of two (complex) vectors."""
    a, b = np.ravel(a), np.ravel(b)
    den = np.real(np.vdot(a, a) * np.vdot(b, b))
    return float(abs(np.vdot(a, b)) ** 2 / den) if den > 0 else 0.0


@dataclass(frozen=True)
class ChartPoint:
    """One pole of the stabilisation chart: its order, pole (rad/s), frequency (Hz), damping ratio,
    residue vector over the FRF rows and status: ``new``, ``freq`` (stable in frequency), ``damp``
    (and damping) or ``stable`` (and shape)."""

    order: int
    pole: complex
    freq_Hz: float
    zeta: float
    residues: np.ndarray
    status: str


@dataclass(frozen=True)
class Cluster:
    """A physical pole: its stable members (one per order) and their medians and scatters."""

    members: tuple
    freq_Hz: float
    zeta: float
    freq_scatter_Hz: float
    zeta_scatter: float

    @property
    def orders(self) -> list[int]:
        return [m.order for m in self.members]


def classify(chart: PoleChart, freq_Hz, H, options: EmaOptions) -> list[ChartPoint]:
    """Every pole of ``chart`` with its residues (LSFD at its order) and stability status."""
    points, previous = [], None
    for order, poles in zip(chart.orders, chart.poles):
        if poles.size == 0:
            previous = []
            continue
        res = lsfd(freq_Hz, H, poles, chart.band_Hz, max_lines=QUICK_LINES).A
        f, z = pole_freq_damping(poles)
        current = []
        for j in range(poles.size):
            status = "new"
            if previous:
                pf = np.array([p.freq_Hz for p in previous])
                k = int(np.argmin(np.abs(pf - f[j])))
                prev = previous[k]
                if abs(prev.freq_Hz - f[j]) <= options.freq_tol_pct / 100 * f[j]:
                    status = "freq"
                    if abs(prev.zeta - z[j]) <= options.damping_tol_pct / 100 * z[j]:
                        status = "damp"
                        if mac(prev.residues, res[:, j]) >= options.mac_min:
                            status = "stable"
            current.append(ChartPoint(int(order), complex(poles[j]), float(f[j]), float(z[j]), res[:, j], status))
        points += current
        previous = current
    return points


def select_physical(points: list[ChartPoint], options: EmaOptions) -> list[Cluster]:
    """The physical poles: chains of stable poles at ``min_stable_orders`` orders or more."""
    stable = sorted((p for p in points if p.status == "stable"), key=lambda p: p.freq_Hz)
    chains, chain = [], []
    for p in stable:
        if chain and p.freq_Hz - chain[-1].freq_Hz > options.freq_tol_pct / 100 * chain[-1].freq_Hz:
            chains.append(chain)
            chain = []
        chain.append(p)
    if chain:
        chains.append(chain)
    clusters = []
    for chain in chains:
        median = float(np.median([p.freq_Hz for p in chain]))
        best = {}
        for p in chain:
            if p.order not in best or abs(p.freq_Hz - median) < abs(best[p.order].freq_Hz - median):
                best[p.order] = p
        members = tuple(best[o] for o in sorted(best))
        if len(members) < options.min_stable_orders:
            continue
        f = np.array([m.freq_Hz for m in members])
        z = np.array([m.zeta for m in members])
        clusters.append(Cluster(members, float(np.median(f)), float(np.median(z)),
                                float(np.std(f, ddof=1)), float(np.std(z, ddof=1))))
    return clusters
