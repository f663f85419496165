"""The 36 named measuring points of the modal test (18 on the table top, 18 on the base top).

The paper (Fig. 6a) used 36 points on the table and base; their exact layout is not published.  This
layout spreads them the same way: a 3 x 6 grid on the table top (T01..T18) and two lines of nine along
the base top outside the carriages (B01..B18), enough to see table rigid-body motion and base bending
and torsion.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd


def measuring_points(geometry: Mapping, dims: dict) -> pd.DataFrame:
    """Measuring-point table: columns ``point, part, x_m, y_m, z_m`` (``geometry``: the rig's description,
    :attr:`jointid.config.typed.RigModel.geometry`).

    Points sit on the top surfaces; coordinates in metres.
    """
    b, t = geometry["base"], geometry["table"]
    zt = t["position_m"]
    rows = []
    tx = np.array([-0.375, 0.0, 0.375]) * t["width_m"]
    tz = zt + np.linspace(-0.4, 0.4, 6) * t["length_m"]
    n = 1
    for z in tz:
        for x in tx:
            rows.append((f"T{n:02d}", "table", x, dims["table_top_m"], z))
            n += 1
    bx = np.array([-0.42, 0.42]) * b["width_m"]
    bz = np.linspace(-0.45, 0.45, 9) * b["length_m"]
    n = 1
    for z in bz:
        for x in bx:
            rows.append((f"B{n:02d}", "base", x, dims["base_top_m"], z))
            n += 1
    return pd.DataFrame(rows, columns=["point", "part", "x_m", "y_m", "z_m"])


def dof_labels(points: pd.DataFrame) -> list[str]:
    """Labels ``<point>:<direction>`` for the 3 directions of each point, in probe-matrix row order."""
    return [f"{p}:{d}" for p in points["point"] for d in "xyz"]
