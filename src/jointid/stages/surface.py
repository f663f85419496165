"""Rules ``fit_surface`` and ``fit_zoom``: track the modes through a DOE and fit the response surfaces.

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`).
"""

from __future__ import annotations

import numpy as np

from jointid import io
from jointid.stages.doe import parameter_bounds, parameter_names
from jointid.stages.runner import log

CONFIG = ("joints", "surface", "solver.min_freq_Hz", "harmonic.band_Hz")
"""Config keys of rules ``fit_surface`` and ``fit_zoom``."""


def tracked_band(cfg: dict) -> tuple[float, float]:
    """Modes of the reference point inside this band are tracked and fitted (Hz)."""
    return float(cfg["solver"]["min_freq_Hz"]), 1.25 * float(cfg["harmonic"]["band_Hz"][1])


def run_fit_surface(cfg: dict, sheet_csv: str, arrays_npz: str, out_json: str, out_csv: str,
                    box_json: str | None = None) -> None:
    """Track the modes through one DOE and fit the surfaces (``box_json``: the zoomed DOE's box)."""
    import pandas as pd

    from jointid.identification.updating import fit_surfaces

    sheet = io.read_csv(sheet_csv)
    z = io.load_npz(arrays_npz)
    descr = z["descriptions"]
    names = parameter_names(cfg)
    doc, diag = fit_surfaces(sheet, z["freqs_Hz"], z["shapes"], descr, names, tracked_band(cfg),
                             kind=cfg["surface"]["kind"])
    if box_json:  # the zoomed second DOE
        box = io.read_json(box_json)
        doc["lower"], doc["upper"], doc["stage"] = list(box["lower"]), list(box["upper"]), "zoom"
    else:
        doc["lower"], doc["upper"] = [b.tolist() for b in parameter_bounds(cfg)]
        doc["stage"] = "global"
    io.write_json(out_json, doc)
    io.write_csv(diag, out_csv)
    worst = diag["verify_max_error_pct"].max()
    log(f"surface: {len(doc['tracked_modes'])} tracked modes, worst verification error {worst:.3f} %")
    limit = cfg["surface"]["max_verification_error_pct"]
    if worst > limit:
        import warnings

        from jointid.errors import NumericalWarning

        warnings.warn(f"surface: verification error {worst:.2f} % exceeds "
                      f"surface.max_verification_error_pct = {limit} %; the final FE verification "
                      "shows its effect on the identified frequencies", NumericalWarning)
