"""Mode identity across DOE points, by MAC.

:func:`track_doe`: each reference mode (modes of the DOE centre point inside the tracked band) is
followed to every other DOE point by the best one-to-one MAC assignment of the shapes at the
measuring points (:func:`jointid.correlate.pairing.pair_by_mac`).  Modes veer and swap order as joint
stiffness changes; order is never used.  The pairing of measured with model modes is in
:mod:`jointid.correlate.pairing`.
"""

from __future__ import annotations

import numpy as np

from jointid.correlate.mac import mac
from jointid.correlate.pairing import pair_by_mac


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
