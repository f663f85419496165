"""Whether a parameter of a linear fit is identifiable when its column is nearly a combination of the
others (the joint damping, :mod:`jointid.identification.joint_damping`).

Collinearity inflates a parameter's variance by ``1 / (1 - R^2)``; the covariance already holds that
inflation.  So a collinear parameter is not identifiable only when the inflated interval is no longer
informative.  Two rules, both needed:

* ``R^2 < COLLINEAR_R2``: not collinear, valued;
* collinear but not singular (``1 - R^2 > SINGULAR``, where the covariance from the pseudo-inverse is
  the inverse's) and its 95 % interval excludes zero (``1.96 sd < |value|``): the data's precision
  determines it all the same, valued with a note.

Everything else is reported as not identifiable, with what it is collinear with.  (On the hammer-test
example's six modes, measured to 0.1-0.3 %, the damping columns are collinear at R^2 0.994-0.9993, yet
zeta0 and the normal loss factor come out within a few per cent of the truth.)
"""

from __future__ import annotations

import numpy as np

__all__ = ["COLLINEAR_R2", "SINGULAR", "collinearity", "valued"]

COLLINEAR_R2 = 0.99
"""A weighted column explained to this uncentred R^2 by the others (1 / (1 - R^2) = 100 times the variance
of an independent column) is collinear with them."""
SINGULAR = 1e-8
"""``1 - R^2`` below this: the column is a combination of the others to rounding; no covariance holds."""
Z95 = 1.96


def collinearity(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column of the weighted design ``A``: uncentred ``R^2`` on the other columns, and the other
    column of largest ``|cos|`` with it (-1 for a single column)."""
    n_col = A.shape[1]
    r2, partner = np.zeros(n_col), np.full(n_col, -1)
    norm = np.linalg.norm(A, axis=0)
    unit = A / np.where(norm > 0, norm, 1.0)
    for j in range(n_col):
        others = np.delete(np.arange(n_col), j)
        if norm[j] == 0:
            r2[j] = 1.0
        elif others.size:
            coef = np.linalg.lstsq(A[:, others], A[:, j], rcond=None)[0]
            r2[j] = 1.0 - float(np.sum((A[:, j] - A[:, others] @ coef) ** 2)) / norm[j] ** 2
        if others.size:
            partner[j] = others[np.argmax(np.abs(unit[:, others].T @ unit[:, j]))]
    return r2, partner


def valued(r2: np.ndarray, x: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Per parameter: whether it gets a value (see the module doc)."""
    r2, x = np.asarray(r2, float), np.asarray(x, float)
    sd = np.sqrt(np.clip(np.diag(np.asarray(cov, float)), 0.0, None))
    determined = (1.0 - r2 > SINGULAR) & np.isfinite(sd) & (Z95 * sd < np.abs(x))
    return (r2 < COLLINEAR_R2) | determined
