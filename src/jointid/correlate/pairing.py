"""Mode pairing and test/analysis correlation tables: frequency errors, MAC pairing, shape residuals.

* :func:`pair_by_mac` is the best one-to-one (Hungarian) assignment on a MAC matrix
  (:func:`jointid.correlate.mac.mac`); :func:`pair_by_shapes` pairs two shape sets by it (measured with
  model modes, a mode with its continuation on a refined mesh or at another parameter point).
* :func:`pair_by_frequency` pairs by an order-preserving assignment that minimises the summed squared
  log-frequency distance (:func:`ordered_assignment`, dynamic programming), when the measurement has
  frequencies only (no shapes).
* :func:`pair_modes` pairs measured with model modes: by MAC (one-to-one, Hungarian) when shapes are
  measured, else by the order-preserving log-frequency assignment.  Measured modes without a partner
  (MAC below the threshold) and model modes inside the measured band that no measured mode took are
  *listed*, never silently dropped.  :func:`pair_states_by_frequency` does the frequency pairing of
  several states with one mode identity across them.
* :func:`frequency_errors` tabulates the per-mode relative error ``(f_model - f_meas) / f_meas``.
* :func:`shape_residuals` scales each paired model shape onto the measured one (modal scale factor,
  least squares) and gives the residual at every measured point DOF; :func:`point_residuals`
  summarises them per measuring point (where the model fails).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from jointid.correlate.mac import mac

__all__ = ["PairedBy", "Pairing", "below_band", "pair_by_mac", "pair_by_shapes", "pair_by_frequency", "ordered_assignment",
           "pair_modes", "pair_shapeless", "pair_states_by_frequency", "frequency_errors", "shape_residuals",
           "point_residuals", "error_summary"]


class PairedBy(str, Enum):
    """How an identification paired its measured modes (``params.json``'s ``paired_by``; the value is the
    text written there, so a record reads back as the same member)."""

    MAC = "mac"
    """By MAC against measured shapes."""
    FREQUENCY = "frequency"
    """By frequency alone, re-paired at every iterate (``identify.pairing: independent``)."""
    FREQUENCY_SHARED = "frequency, shared by all states"
    """By frequency alone, one pairing shared by all frequency-only states (``identify.pairing: shared``)."""

    @property
    def by_frequency(self) -> bool:
        """Paired without shapes."""
        return self is not PairedBy.MAC

    @classmethod
    def of(cls, record: dict) -> "PairedBy | None":
        """The member a record's ``paired_by`` names (None where it names none)."""
        try:
            return cls(record.get("paired_by"))
        except ValueError:
            return None


@dataclass
class Pairing:
    """Measured-to-model mode pairing of one state.

    Attributes
    ----------
    model_index : ndarray (m,)
        Model mode index paired with each measured mode, -1 if unpaired.
    mac : ndarray (m,)
        MAC of each pair (NaN when paired by frequency only).
    method : str
        ``mac`` or ``frequency``.
    unpaired_measured : list of int
        Measured modes (0-based) without a model partner.
    unpaired_model : list of int
        Model modes inside the measured band (0-based) that no measured mode took.
    """

    model_index: np.ndarray
    mac: np.ndarray
    method: str
    unpaired_measured: list = field(default_factory=list)
    unpaired_model: list = field(default_factory=list)

    @property
    def paired(self) -> np.ndarray:
        """Indices of the measured modes that have a partner."""
        return np.flatnonzero(self.model_index >= 0)


def below_band(dataset: str, freqs_by_state: dict, min_freq_Hz: float) -> list[str]:
    """Problem lines for measured modes below ``solver.min_freq_Hz``: model modes there count as
    rigid-body or mount modes and are never paired, so such a measured mode would be paired with an
    unrelated model mode."""
    return [f"{dataset}: measured {state} mode {i + 1} at {f:g} Hz lies below solver.min_freq_Hz = "
            f"{min_freq_Hz:g} Hz, under which model modes count as rigid-body or mount modes and are never "
            "paired — lower solver.min_freq_Hz below the lowest measured mode"
            for state, freqs in freqs_by_state.items() for i, f in enumerate(freqs) if f < min_freq_Hz]


def pair_by_mac(macs: np.ndarray, threshold: float = 0.5) -> list[tuple[int, int, float]]:
    """Best one-to-one pairing (Hungarian) of rows (e.g. measured) to columns (model) by MAC.

    Pairs with MAC below ``threshold`` are dropped (reported as unpaired by the caller).
    Returns ``[(row, col, mac), ...]`` sorted by row.
    """
    rows, cols = linear_sum_assignment(-macs)
    return [(int(r), int(c), float(macs[r, c])) for r, c in zip(rows, cols)
            if macs[r, c] >= threshold]


def pair_by_shapes(shapes_a: np.ndarray, shapes_b: np.ndarray, threshold: float = 0.5):
    """Mode of set b paired with each mode of set a by MAC (one-to-one, :func:`pair_by_mac`).

    Parameters
    ----------
    shapes_a, shapes_b : ndarray, shape (n_labels, m) and (n_labels, n)
        Shapes at the same labels (e.g. measured and model shapes at the measuring-point DOFs, or one
        model's shapes on two meshes); labels NaN in either set are ignored.
    threshold : float
        Smallest MAC accepted for a pair.

    Returns
    -------
    index : ndarray of int, shape (m,)
        Mode of set b paired with each mode of set a, -1 where none reaches ``threshold``.
    mac : ndarray, shape (m,)
        MAC of each pair (0 where unpaired).
    """
    m = mac(shapes_a, shapes_b)
    index = -np.ones(m.shape[0], dtype=int)
    value = np.zeros(m.shape[0])
    for r, c, v in pair_by_mac(m, threshold):
        index[r], value[r] = c, v
    return index, value


def pair_by_frequency(f_meas: np.ndarray, f_model: np.ndarray, skip_cost: np.ndarray | None = None) -> np.ndarray:
    """Order-preserving assignment of measured modes to model modes by log-frequency distance.

    ``f_meas`` (m,) and ``f_model`` (n,), n >= m, in Hz.  ``skip_cost`` (n,), in the same units as the
    squared log distance: the cost of leaving each model mode unpaired (0, the default, for a mode the
    test need not have seen; :mod:`jointid.correlate.observability` for one it would have).  Returns
    the model index for each measured mode (strictly increasing in the model's frequency order).
    """
    fm = np.log(np.asarray(f_meas, float))
    order = np.argsort(f_model)
    fc = np.log(np.asarray(f_model, float)[order])
    if len(fc) < len(fm):
        raise ValueError(f"{len(fm)} measured modes but only {len(fc)} model modes to pair with")
    skip = None if skip_cost is None else np.asarray(skip_cost, float)[order]
    return order[ordered_assignment((fm[:, None] - fc[None, :]) ** 2, skip_cost=skip)]


def ordered_assignment(cost: np.ndarray, skip_cost: np.ndarray | None = None) -> np.ndarray:
    """Order-preserving assignment of rows to columns minimising the summed cost.

    ``cost`` is ``(m, n)`` with ``n >= m``; ``skip_cost`` (n,) is what leaving each column unassigned
    costs (default: nothing).  Returns the column of each row, strictly increasing (dynamic
    programming, O(m n)).
    """
    m, n = cost.shape
    if n < m:
        raise ValueError(f"{m} rows but only {n} columns to assign")
    s = np.zeros(n) if skip_cost is None else np.asarray(skip_cost, float)
    D = np.full((m + 1, n + 1), np.inf)
    D[0, :] = np.concatenate([[0.0], np.cumsum(s)]) if skip_cost is not None else 0.0
    take = np.zeros((m + 1, n + 1), bool)
    for i in range(1, m + 1):
        for j in range(i, n + 1):
            skip = D[i, j - 1] + s[j - 1] if skip_cost is not None else D[i, j - 1]
            use = D[i - 1, j - 1] + cost[i - 1, j - 1]
            if use <= skip:
                D[i, j], take[i, j] = use, True
            else:
                D[i, j] = skip
    out = np.empty(m, dtype=int)
    i, j = m, n
    while i > 0:
        if take[i, j]:
            out[i - 1] = j - 1
            i -= 1
        j -= 1
    return out


def pair_modes(f_meas, f_model, meas_shapes=None, model_shapes=None, *, threshold: float = 0.5,
               min_freq_Hz: float = 0.0) -> Pairing:
    """Pair measured modes with model modes.

    Parameters
    ----------
    f_meas : (m,) measured frequencies, Hz.
    f_model : (n,) model frequencies, Hz (ascending).
    meas_shapes, model_shapes : (n_labels, m), (n_labels, n), optional
        Shapes at the measuring-point DOFs; when both are given the pairing is by MAC.
    threshold : float
        Smallest MAC accepted for a pair.
    min_freq_Hz : float
        Model modes below this (rigid-body, mount modes) are never paired.

    Returns
    -------
    Pairing
    """
    f_meas = np.asarray(f_meas, float)
    f_model = np.asarray(f_model, float)
    m = len(f_meas)
    usable = np.flatnonzero(f_model >= min_freq_Hz)
    index = -np.ones(m, dtype=int)
    macs = np.full(m, np.nan)
    if meas_shapes is not None and model_shapes is not None and np.isfinite(meas_shapes).any():
        meas_shapes = np.asarray(meas_shapes, float)
        M = mac(meas_shapes, np.asarray(model_shapes, float)[:, usable])
        for r, c, v in pair_by_mac(M, threshold):
            index[r], macs[r] = usable[c], v
        method = "mac"
        pair_shapeless(f_meas, f_model, usable, index, ~np.isfinite(meas_shapes).any(axis=0))
    else:
        if len(usable) >= m:
            index = usable[pair_by_frequency(f_meas, f_model[usable])]
        else:
            index[: len(usable)] = usable[pair_by_frequency(f_meas[: len(usable)], f_model[usable])]
        method = "frequency"
    taken = set(index[index >= 0].tolist())
    hi = f_meas.max() * 1.02 if m else 0.0
    lo = max(min_freq_Hz, f_meas.min() * 0.98) if m else 0.0
    unpaired_model = [int(j) for j in usable if lo <= f_model[j] <= hi and j not in taken]
    return Pairing(model_index=index, mac=macs, method=method,
                   unpaired_measured=[int(i) for i in np.flatnonzero(index < 0)],
                   unpaired_model=unpaired_model)


def pair_shapeless(f_meas, f_model, usable, index: np.ndarray, shapeless: np.ndarray) -> None:
    """Pair, in place, the measured modes whose shape is missing (``shapeless``) by frequency.

    Their partners are chosen among the ``usable`` model modes that no shape took, by the
    order-preserving log-frequency assignment (:func:`pair_by_frequency`); a missing shape only
    removes that mode's shape information, its frequency still counts.
    """
    rows = np.flatnonzero(np.asarray(shapeless) & (index < 0))
    free = np.array([j for j in usable if j not in set(index[index >= 0].tolist())], int)
    if not len(rows) or not len(free):
        return
    n = min(len(rows), len(free))
    rows = rows[np.argsort(f_meas[rows])][:n] if len(rows) > len(free) else rows
    index[rows] = free[pair_by_frequency(f_meas[rows], f_model[free])]


def pair_states_by_frequency(f_meas: list, f_model: list, tracks: list, *, min_freq_Hz: float = 0.0,
                             skip_cost: list | None = None) -> list:
    """Frequency-only pairing of several states with one mode identity across the states.

    Measured mode ``i`` is taken to be the same physical mode in every state (same count of modes,
    numbered by frequency), and the model modes of each state are identified with those of the first
    state by ``tracks``.  The order-preserving assignment minimises the squared log-frequency
    distance summed over the states, so a mode cannot pair with a bounce mode in one state and a
    pitch mode in the other.

    Parameters
    ----------
    f_meas : list of (m,) arrays, one per state (same m).
    f_model : list of (n,) arrays of model frequencies per state.
    tracks : list of (n,) int arrays; ``tracks[s][j]`` is the model mode of state s continuing mode j
        of the first state (-1 if lost); ``tracks[0]`` is the identity.
    min_freq_Hz : float
        First-state model modes below this are never paired.
    skip_cost : list of (n,) arrays, optional
        Per state, the cost (squared log frequency, the units of the assignment) of leaving each
        model mode unpaired (the observability rule's misfits); summed over the states along the
        tracks.  Default: skipping is free.

    Returns
    -------
    list of Pairing, one per state.
    """
    f0 = np.asarray(f_model[0], float)
    ok = [j for j in np.argsort(f0) if f0[j] >= min_freq_Hz and all(t[j] >= 0 for t in tracks)]
    m = len(f_meas[0])
    cost = np.zeros((m, len(ok)))
    for fm, fs, tr in zip(f_meas, f_model, tracks):
        fs = np.asarray(fs, float)
        cost += (np.log(np.asarray(fm, float))[:, None] - np.log(fs[np.asarray(tr)[ok]])[None, :]) ** 2
    skip = None
    if skip_cost is not None:
        skip = np.zeros(len(ok))
        for sc, tr in zip(skip_cost, tracks):
            skip += np.asarray(sc, float)[np.asarray(tr)[ok]]
    cols = ordered_assignment(cost, skip_cost=skip) if len(ok) >= m else None
    out = []
    for fm, fs, tr in zip(f_meas, f_model, tracks):
        fm, fs = np.asarray(fm, float), np.asarray(fs, float)
        if cols is None:
            out.append(pair_modes(fm, fs, min_freq_Hz=min_freq_Hz))
            continue
        index = np.asarray(tr)[np.asarray(ok)[cols]]
        taken = set(index.tolist())
        hi, lo = fm.max() * 1.02, max(min_freq_Hz, fm.min() * 0.98)
        unpaired_model = [int(j) for j in range(len(fs)) if lo <= fs[j] <= hi and j not in taken]
        out.append(Pairing(model_index=index.astype(int), mac=np.full(m, np.nan), method="frequency",
                           unpaired_measured=[], unpaired_model=unpaired_model))
    return out


def frequency_errors(state: str, f_meas, f_model, pairing: Pairing, descriptions=None) -> pd.DataFrame:
    """Per-mode comparison table of one state.

    Columns ``state, mode, freq_meas_Hz, freq_model_Hz, error_pct, model_mode, mac, status,
    description``; ``mode``/``model_mode`` are 1-based; ``status`` is ``paired``,
    ``unpaired_measured`` or ``unpaired_model`` (a model mode inside the band that no measured mode
    took).
    """
    f_meas = np.asarray(f_meas, float)
    f_model = np.asarray(f_model, float)
    rows = []
    for i, j in enumerate(pairing.model_index):
        if j >= 0:
            rows.append({"state": state, "mode": i + 1, "freq_meas_Hz": f_meas[i], "freq_model_Hz": f_model[j],
                         "error_pct": 100 * (f_model[j] - f_meas[i]) / f_meas[i], "model_mode": int(j) + 1,
                         "mac": pairing.mac[i], "status": "paired",
                         "description": "" if descriptions is None else str(descriptions[j])})
        else:
            rows.append({"state": state, "mode": i + 1, "freq_meas_Hz": f_meas[i], "freq_model_Hz": np.nan,
                         "error_pct": np.nan, "model_mode": 0, "mac": np.nan, "status": "unpaired_measured",
                         "description": "no model mode pairs with this measured mode"})
    for j in pairing.unpaired_model:
        rows.append({"state": state, "mode": 0, "freq_meas_Hz": np.nan, "freq_model_Hz": f_model[j],
                     "error_pct": np.nan, "model_mode": int(j) + 1, "mac": np.nan, "status": "unpaired_model",
                     "description": ("model mode in the band not seen in the test" if descriptions is None
                                     else f"{descriptions[j]} (not seen in the test)")})
    return pd.DataFrame(rows)


def error_summary(errors: pd.DataFrame) -> pd.DataFrame:
    """Per-state ``max_abs_error_pct``, ``rms_error_pct`` and counts from :func:`frequency_errors`."""
    out = []
    for state, g in errors.groupby("state", sort=False):
        e = g.loc[g.status == "paired", "error_pct"].to_numpy(float)
        out.append({"state": state, "n_paired": len(e),
                    "n_unpaired_measured": int((g.status == "unpaired_measured").sum()),
                    "n_unpaired_model": int((g.status == "unpaired_model").sum()),
                    "max_abs_error_pct": float(np.abs(e).max()) if len(e) else np.nan,
                    "rms_error_pct": float(np.sqrt(np.mean(e ** 2))) if len(e) else np.nan})
    return pd.DataFrame(out)


def shape_residuals(state: str, meas_shapes, model_shapes, pairing: Pairing, labels) -> pd.DataFrame:
    """Shape residual at each measured point DOF of each paired mode.

    Each measured shape is normalised to unit length; the model shape is scaled onto it by the
    modal scale factor ``a = (s . m) / (s . s)`` (least squares, fixes sign and scale).

    Returns
    -------
    DataFrame
        ``state, mode, point, direction, measured, model, residual`` (dimensionless, shapes of unit
        norm); empty if nothing was measured.
    """
    rows = []
    if meas_shapes is None:
        return pd.DataFrame(columns=["state", "mode", "point", "direction", "measured", "model", "residual"])
    meas = np.asarray(meas_shapes, float)
    model = np.asarray(model_shapes, float)
    for i, j in enumerate(pairing.model_index):
        if j < 0:
            continue
        ok = np.isfinite(meas[:, i])
        if not ok.any():
            continue
        mv = meas[ok, i] / np.linalg.norm(meas[ok, i])
        sv = model[ok, j]
        a = float(sv @ mv) / float(sv @ sv) if sv @ sv > 0 else 0.0
        for lab, mvk, svk in zip(np.asarray(labels)[ok], mv, a * sv):
            point, direction = lab.split(":")
            rows.append({"state": state, "mode": i + 1, "point": point, "direction": direction,
                         "measured": mvk, "model": svk, "residual": svk - mvk})
    return pd.DataFrame(rows, columns=["state", "mode", "point", "direction", "measured", "model", "residual"])


def point_residuals(residuals: pd.DataFrame) -> pd.DataFrame:
    """RMS shape residual per measuring point over modes and directions (where the model fails).

    Columns ``point, rms_residual, n_values``, sorted worst first.
    """
    if residuals.empty:
        return pd.DataFrame(columns=["point", "rms_residual", "n_values"])
    g = residuals.groupby("point")["residual"]
    out = pd.DataFrame({"rms_residual": g.apply(lambda s: float(np.sqrt(np.mean(np.square(s))))),
                        "n_values": g.size()}).reset_index()
    return out.sort_values("rms_residual", ascending=False, kind="stable").reset_index(drop=True)
