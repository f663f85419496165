"""What the FE polish fits (:class:`PolishFit`): the measured modes, the shapes they follow, the
bounds, the noise and the visibility rule (:func:`jointid.identification.polish.fe_polish`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointid.identification.visibility import VisibilityRule

__all__ = ["PolishFit"]


@dataclass(frozen=True)
class PolishFit:
    """What the FE polish fits.

    Parameters
    ----------
    f_meas_Hz : ndarray, shape (n_meas,)
        Measured frequencies, Hz.
    ref_shapes : ndarray, shape (n_labels, n_meas)
        Shapes the measured modes follow by MAC (the tracked reference shapes of the paired modes).
    lower_N_per_m3, upper_N_per_m3 : ndarray, shape (n_params,)
        Bounds of the joint parameters, N/m^3.
    weights : ndarray, shape (n_meas,), optional
        Weight of each measured mode (default 1).
    sigma_rel : float
        Relative frequency uncertainty (dimensionless), the scale of the covariance.
    repair : bool
        Frequency-only data: re-pair the measured modes by frequency at every iterate.
    rule : VisibilityRule, optional
        Modes the test would clearly have seen count as misfits when no measured mode takes them.
    shapes : ndarray, shape (n_labels, n_meas), optional
        Measured shapes at the solve's probe labels (NaN where not measured).  Where given, every
        measured mode adds its shape rows to the fit (:mod:`jointid.correlate.shape_rows`), a block
        judged with its own model error.
    shape_sigma_rel : float, optional
        Stated shape uncertainty (fraction of each mode's RMS); None: estimated from the misfit at the
        start (an upper bound of the noise).
    """

    f_meas_Hz: np.ndarray
    ref_shapes: np.ndarray
    lower_N_per_m3: np.ndarray
    upper_N_per_m3: np.ndarray
    weights: np.ndarray | None = None
    sigma_rel: float = 0.01
    repair: bool = False
    rule: VisibilityRule | None = None
    shapes: np.ndarray | None = None
    shape_sigma_rel: float | None = None

    @property
    def has_shapes(self) -> bool:
        """Whether any measured mode has a shape at two or more DOFs (shape rows in the fit)."""
        return self.shapes is not None and bool((np.isfinite(self.shapes).sum(axis=0) >= 2).any())
