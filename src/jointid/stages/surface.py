"""Rules ``fit_surface`` and ``fit_zoom``: track the modes through a DOE and fit the response surfaces.

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.options import SurfaceOptions



def run_fit_surface(opts: SurfaceOptions, sheet_csv: str, arrays_npz: str, out_json: str, out_csv: str,
                    box_json: str | None = None) -> None:
    """Track the modes through one DOE and fit the surfaces (``box_json``: the zoomed DOE's box)."""
    doc, diag = surfaces(opts, io.read_csv(sheet_csv), io.load_npz(arrays_npz),
                         io.read_json(box_json) if box_json else None)
    io.write_json(out_json, doc)
    io.write_csv(diag, out_csv)
    check_surfaces(opts, doc, diag)


def surfaces(opts: SurfaceOptions, sheet, arrays: dict, box: dict | None = None):
    """The response surfaces of one DOE (its sample sheet and the gathered modes' ``arrays``,
    :func:`jointid.stages.modal.gathered`), over its box (``box``: the zoomed DOE's record, else the bounds of
    ``joints.parameters``): ``(surface model, diagnostics table)``."""
    from jointid.identification.updating import fit_surfaces

    names = opts.joints.names
    doc, diag = fit_surfaces(sheet, arrays["freqs_Hz"], arrays["shapes"], arrays["descriptions"], names,
                             opts.tracked_band_Hz, kind=opts.kind)
    if box:  # the zoomed second DOE
        doc["lower"], doc["upper"], doc["stage"] = list(box["lower"]), list(box["upper"]), "zoom"
    else:
        doc["lower"], doc["upper"] = opts.joints.lower_N_per_m3.tolist(), opts.joints.upper_N_per_m3.tolist()
        doc["stage"] = "global"
    return doc, diag


def check_surfaces(opts: SurfaceOptions, doc: dict, diag) -> None:
    """Log the surfaces' worst verification error; warn where it exceeds ``surface.max_verification_error_pct``."""
    worst = diag["verify_max_error_pct"].max()
    log(f"surface: {len(doc['tracked_modes'])} tracked modes, worst verification error {worst:.3f} %")
    limit = opts.max_verification_error_pct
    if worst > limit:
        import warnings

        from jointid.errors import NumericalWarning

        warnings.warn(f"surface: verification error {worst:.2f} % exceeds "
                      f"surface.max_verification_error_pct = {limit} %; the final FE verification "
                      "shows its effect on the identified frequencies", NumericalWarning)
