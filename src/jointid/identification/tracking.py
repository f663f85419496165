"""Mode identity across DOE points (by MAC) and pairing of measured modes with model modes.

* :func:`track_doe`: each reference mode (modes of the DOE centre point inside the tracked band) is
  followed to every other DOE point by the best one-to-one MAC assignment of the shapes at the
  measuring points.  Modes veer and swap order as joint stiffness changes; order is never used.
* :func:`pair_by_frequency`: when the measurement has frequencies only (no shapes), measured modes are
  paired with model modes by an order-preserving assignment that minimises the summed squared
  log-frequency distance (dynamic programming).  Model modes left out are reported as unpaired
  ("not seen in the test"), never silently dropped.
* With measured shapes, :func:`jointid.fe.modal.pair_by_mac` is used instead.
"""

from __future__ import annotations

import numpy as np

from jointid.fe.modal import mac, pair_by_mac


def track_doe(freqs: np.ndarray, shapes: np.ndarray, ref: int, band_Hz: tuple[float, float],
              threshold: float = 0.5):
    """Follow the reference point's modes through all DOE points.

    Parameters
    ----------
    freqs : (n_points, n_modes) natural frequencies in Hz at each DOE point
    shapes : (n_points, n_labels, n_modes) shapes at the measuring points
    ref : index of the reference (centre) point
    band_Hz : (low, high) modes of the reference inside this band are tracked

    Returns
    -------
    ref_modes : (r,) indices of the tracked modes at the reference point
    tracked_f : (n_points, r) frequency of each tracked mode (NaN where lost)
    tracked_mac : (n_points, r) MAC with the reference shape
    """
    f0 = freqs[ref]
    ref_modes = np.flatnonzero((f0 >= band_Hz[0]) & (f0 <= band_Hz[1]))
    ref_shapes = shapes[ref][:, ref_modes]
    n_points = freqs.shape[0]
    tf = np.full((n_points, len(ref_modes)), np.nan)
    tm = np.zeros((n_points, len(ref_modes)))
    for p in range(n_points):
        m = mac(ref_shapes, shapes[p])
        for r, c, v in pair_by_mac(m, threshold):
            tf[p, r], tm[p, r] = freqs[p, c], v
    return ref_modes, tf, tm


def pair_by_frequency(f_meas: np.ndarray, f_model: np.ndarray) -> np.ndarray:
    """Order-preserving assignment of measured modes to model modes by log-frequency distance.

    ``f_meas`` (m,) and ``f_model`` (n,), n >= m.  Returns the model index for each measured mode
    (strictly increasing in the model's frequency order).
    """
    fm = np.log(np.asarray(f_meas, float))
    order = np.argsort(f_model)
    fc = np.log(np.asarray(f_model, float)[order])
    if len(fc) < len(fm):
        raise ValueError(f"{len(fm)} measured modes but only {len(fc)} model modes to pair with")
    return order[ordered_assignment((fm[:, None] - fc[None, :]) ** 2)]


def ordered_assignment(cost: np.ndarray) -> np.ndarray:
    """Order-preserving assignment of rows to columns minimising the summed cost.

    ``cost`` is ``(m, n)`` with ``n >= m``; returns the column of each row, strictly increasing
    (dynamic programming, O(m n)).
    """
    m, n = cost.shape
    if n < m:
        raise ValueError(f"{m} rows but only {n} columns to assign")
    D = np.full((m + 1, n + 1), np.inf)
    D[0, :] = 0.0
    take = np.zeros((m + 1, n + 1), bool)
    for i in range(1, m + 1):
        for j in range(i, n + 1):
            skip = D[i, j - 1]
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


def pair_by_shapes(meas_shapes: np.ndarray, model_shapes: np.ndarray, threshold: float = 0.5):
    """MAC pairing of measured shapes ``(n_labels, m)`` with model shapes ``(n_labels, n)``.

    Returns ``(index (m,), mac (m,))`` with index -1 for measured modes left unpaired.
    """
    m = mac(meas_shapes, model_shapes)
    index = -np.ones(m.shape[0], dtype=int)
    value = np.zeros(m.shape[0])
    for r, c, v in pair_by_mac(m, threshold):
        index[r], value[r] = c, v
    return index, value
