"""Rules ``doe`` and ``doe_zoom``: the DOE sample sheets (one row per FE solve).

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`); the
Snakefile calls :func:`doe_rows` at parse time for the point names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    import pandas as pd

    from jointid.config.options import DoeOptions



def doe_sheet(opts: DoeOptions, lower=None, upper=None) -> pd.DataFrame:
    """The DOE as a sample sheet: one row per FE solve (design points, then verification points).

    Columns: ``point, role, x_<param>`` (coded in [-1, 1] over log10 of the parameter) and
    ``<param>`` (physical, N/m^3).  The box is ``joints.parameters``' bounds unless ``lower`` and
    ``upper`` (N/m^3) are given (the zoomed second DOE, :func:`zoom_box`).
    """
    import pandas as pd

    return pd.DataFrame(doe_rows(opts, lower, upper))


def doe_rows(opts: DoeOptions, lower=None, upper=None) -> list[dict]:
    """The rows of :func:`doe_sheet` as dicts, without pandas: what the Snakefile reads at parse time (the point
    names, a point's parameters).  Snakemake itself imports pandas later in a start, to compare the params."""
    from jointid.identification.doe import design, to_physical, verification_points

    names = opts.joints.names
    X = design(opts.design, len(names), n_center=opts.n_center, n_samples=opts.n_samples, seed=opts.seed)
    V = verification_points(opts.n_verification, len(names), seed=opts.seed + 1)
    lo, hi = opts.joints.lower_N_per_m3, opts.joints.upper_N_per_m3
    if lower is not None:
        lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    rows = []
    for role, block in (("design", X), ("verify", V)):
        theta = to_physical(block, lo, hi)
        for i in range(len(block)):
            row = {"point": f"{role[0]}{i:03d}", "role": role}
            row.update({f"x_{n}": float(block[i, j]) for j, n in enumerate(names)})
            row.update({n: float(theta[i, j]) for j, n in enumerate(names)})
            rows.append(row)
    return rows


def run_doe(opts: DoeOptions, out_csv: str) -> None:
    """Rule ``doe``: the sample sheet of the first DOE over the whole bounds -> ``out_csv``."""
    sheet = doe_sheet(opts)
    io.write_csv(sheet, out_csv)
    log(f"doe: {int((sheet.role == 'design').sum())} design + {int((sheet.role == 'verify').sum())} "
        f"verification points -> {out_csv}")


def zoom_box(opts: DoeOptions, optima: dict[str, dict[str, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Box of the zoomed second DOE around the first-stage optima of all states (N/m^3).

    Per parameter: ``[min over states / 10^w, max over states * 10^w]`` with ``w =
    doe.zoom.half_width_decades``, clipped to the bounds of ``joints.parameters``; a box squeezed
    against a bound keeps its full width ``2 w`` on the inside.
    """
    names = opts.joints.names
    w = opts.zoom_half_width_decades
    lo_b, hi_b = np.log10(opts.joints.lower_N_per_m3), np.log10(opts.joints.upper_N_per_m3)
    opt = np.log10(np.array([[float(o[n]) for n in names] for o in optima.values()]))
    lo, hi = opt.min(axis=0) - w, opt.max(axis=0) + w
    span = np.minimum(hi - lo, hi_b - lo_b)
    lo, hi = np.maximum(lo, lo_b), np.minimum(hi, hi_b)
    hi = np.maximum(hi, np.minimum(lo + span, hi_b))
    lo = np.minimum(lo, np.maximum(hi - span, lo_b))
    return 10.0 ** lo, 10.0 ** hi


def run_doe_zoom(opts: DoeOptions, scout_jsons: dict[str, str], out_csv: str, out_json: str) -> None:
    """Rule ``doe_zoom``: the same design in :func:`zoom_box` around the states' surface optima."""
    sheet, box = zoom_sheet(opts, {s: io.read_json(p)["surface_optimum"] for s, p in scout_jsons.items()})
    io.write_json(out_json, box)
    io.write_csv(sheet, out_csv)
    log(f"doe zoom: {len(sheet)} points -> {out_csv}")


def zoom_sheet(opts: DoeOptions, optima: dict[str, dict[str, float]]):
    """The zoomed DOE's sample sheet in :func:`zoom_box` around the states' surface optima (``optima``: state ->
    parameter -> N/m^3) and its box's record (``box.json``): ``(sheet, box)``."""
    names = opts.joints.names
    lo, hi = zoom_box(opts, optima)
    log("doe zoom: " + ", ".join(f"{n} {a:.3g}..{b:.3g}" for n, a, b in zip(names, lo, hi)))
    return doe_sheet(opts, lo, hi), {"names": names, "lower": lo.tolist(), "upper": hi.tolist(),
                                     "half_width_decades": opts.zoom_half_width_decades, "first_stage_optima": optima}


def sheet_theta(sheet_csv: str, point: str, names: list[str]) -> dict[str, float]:
    """Physical parameters (N/m^3) of one point of a DOE sample sheet."""
    import pandas as pd

    sheet = io.read_csv(sheet_csv).set_index("point")
    if point not in sheet.index:
        from jointid.errors import DataError

        raise DataError(f"doe: point {point} is not in {sheet_csv} (points: {', '.join(sheet.index)})")
    return {n: float(sheet.loc[point, n]) for n in names}
