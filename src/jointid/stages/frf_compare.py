"""Measured FRFs against the model's, for rule ``harmonic`` (issue 40, item 3).

When the state's dataset has ``frf.csv``, :func:`write_frf_comparison` computes the model receptance at
the identified optimum (the harmonic stage's modes and damping) for every measured ``(point,
direction)`` under the measured excitation (``frf_drive_point``, ``frf_drive_direction`` of
conditions.yaml) and writes, beside ``dynamic_stiffness.json`` in ``results/harmonic/<state>/``:

* ``frf_compare.csv``: :func:`jointid.correlate.frf.compare_table` (FRAC, CSAC, CSF, log-magnitude RMS);
* ``frf_measured_stiffness.json``: the drive-point dynamic stiffness read from the measured FRF
  (:func:`jointid.response.measured.measured_dynamic_stiffness`) beside Table 1's model value;
* ``frf_overlay_measured.png``: measured and model magnitude, one panel per FRF (up to 6).

Model FRF: modal superposition of the harmonic stage's modes (every mode up to 2.5 x the band top) with
its damping ratios.  The excitation is the hammer patch of Table 1 (``drive_points.npz``'s participation
and drive-point residual flexibility) when the measured drive point is a table point struck in
``harmonic.direction``, else a point load; a response at the drive point in the drive direction is the
same patch (so that FRF is Table 1's), any other response is the displacement at the point
(``model.probe``) without residual flexibility (the static share of the modes above 2.5 x the band top
is left out of transfer FRFs).  Without ``frf.csv`` the three files are written all the same (they are
declared outputs of the rule) and say so: the table has its columns and no row, the JSON is
``{"state", "available": false, "note"}``, the figure a panel with that note.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from jointid import io
from jointid.correlate.frf import COMPARE_COLUMNS, compare_table
from jointid.errors import JointidError
from jointid.response.drive_point import drive_vector
from jointid.response.harmonic import frf_modal, resonance_grid
from jointid.response.measured import measured_dynamic_stiffness

if TYPE_CHECKING:
    from jointid.config.options import HarmonicOptions

__all__ = ["OUTPUTS", "model_curves", "write_frf_comparison"]

OUTPUTS = ("frf_compare.csv", "frf_measured_stiffness.json", "frf_overlay_measured.png")
"""Files written into the state's ``results/harmonic/<state>/`` folder (declared outputs of rule ``harmonic``)."""
NO_FRF = "no measured FRF: the dataset has no frf.csv for this state"
"""What the three files say without measured FRFs."""


def _measured(folder: str, state: str, progress):
    """``(dataset, drive_point, drive_direction)`` of the state's measured FRFs, or None without any (or
    when the dataset cannot be read here: the identify stage has validated it, so that is said only)."""
    from jointid.data.dataset import read_dataset

    try:
        ds = read_dataset(folder)
    except (JointidError, OSError) as exc:
        progress(f"harmonic[{state}]: dataset not readable here ({str(exc).splitlines()[0]}): no FRF comparison")
        return None
    if ds.frf is None or state not in set(ds.frf["state"]):
        return None
    cond = ds.state_conditions(state)
    return ds, str(cond["frf_drive_point"]), str(cond.get("frf_drive_direction", "y"))


def _excitation(model, modes, pts: dict, drive: str, direction: str) -> tuple[np.ndarray, float, str]:
    """Modal participation ``p^T phi`` (m/sqrt(kg) per N) of the measured excitation, its drive-point
    residual flexibility (m/N) and a note on what was used."""
    names = [str(p) for p in pts["points"]]
    if drive in names and direction == str(pts["direction"]):
        k = names.index(drive)
        r = float(pts["residual_m_per_N"][k])
        return (np.asarray(pts["pphi"][k], float), r if np.isfinite(r) else 0.0,
                f"hammer patch of {float(pts['patch_diameter_m']) * 1e3:g} mm at {drive} in {direction} (Table 1's), "
                "with its residual flexibility" if np.isfinite(r) else "without residual flexibility (K singular)")
    p = drive_vector(model, drive, direction)
    return p @ modes.phi, 0.0, f"point load at {drive} in {direction}, without residual flexibility"


def model_curves(model, modes, res, pts: dict, ds, state: str, drive: str, direction: str) -> tuple[list, str]:
    """Measured and model FRF of every measured ``(point, direction)`` of ``state``.

    Parameters
    ----------
    model : jointid.fe.fem.Model
        The model (measuring points, ``probe``).
    modes : jointid.fe.modal.Modes
        The harmonic stage's modes (``phi (n_dofs, n_modes)``).
    res : jointid.response.drive_point.HarmonicResult
        Its response (``freqs_Hz``, ``zeta`` ``(n_modes,)``).
    pts : dict
        ``drive_points.npz`` content (:func:`jointid.stages.harmonic.point_data`).
    ds : jointid.data.dataset.Dataset
        The dataset with ``frf.csv``.
    state, drive, direction : str
        State, measured drive point and direction.

    Returns
    -------
    (list of dict, str)
        The curves for :func:`jointid.correlate.frf.compare_table` (``f_model_Hz (n_model,)`` a resonance
        grid over the measured lines holding them, ``H_model`` in m/N), each with ``drive_point`` (bool);
        and the note on the excitation.
    """
    pdrive, r_drive, note = _excitation(model, modes, pts, drive, direction)
    frf = ds.frf[ds.frf["state"] == state]
    curves = []
    for (point, d), _ in frf.groupby(["point", "direction"], sort=False):
        f, H = ds.frf_curve(state, point, d)
        grid = np.union1d(resonance_grid(float(f[0]), float(f[-1]), res.freqs_Hz, res.zeta), f)
        at_drive = (point, d) == (drive, direction)
        presp = pdrive if at_drive else drive_vector(model, point, d) @ modes.phi
        Hm = frf_modal(grid, res.freqs_Hz, res.zeta, pdrive, presp, residual_flexibility=r_drive if at_drive else 0.0)
        curves.append({"state": state, "point": str(point), "direction": str(d), "f_meas_Hz": f, "H_meas": H,
                       "f_model_Hz": grid, "H_model": Hm, "drive_point": at_drive})
    return curves, note


def _stiffness_doc(curves: list, band: list[float], table1: dict, drive: str, direction: str, note: str) -> dict:
    """``frf_measured_stiffness.json``: the measured drive-point dynamic stiffness over Table 1's band,
    the model's FRF read the same way on the measured lines, and Table 1's model value."""
    doc = {"state": table1["state"], "available": True, "drive_point": drive, "direction": direction, "excitation": note,
           "table1_drive_point": table1["drive_point"], "table1_direction": table1["direction"],
           "model_table1": {"dynamic_stiffness_N_per_m": table1["dynamic_stiffness_N_per_m"],
                            "dynamic_stiffness_N_per_mm": table1["dynamic_stiffness_N_per_mm"],
                            "f_at_min_Hz": table1["f_at_min_Hz"]}}
    c = next((c for c in curves if c["drive_point"]), None)
    if c is None:
        doc["measured"] = None
        doc["note"] = f"no FRF measured at the drive point {drive} in {direction}: no measured dynamic stiffness"
        return doc
    f = c["f_meas_Hz"]
    lo, hi = max(band[0], float(f[0])), min(band[1], float(f[-1]))
    doc["band_Hz"] = [lo, hi]
    doc["measured"] = measured_dynamic_stiffness(f, c["H_meas"], (lo, hi))
    Hm = np.interp(f, c["f_model_Hz"], c["H_model"].real) + 1j * np.interp(f, c["f_model_Hz"], c["H_model"].imag)
    doc["model_on_measured_lines"] = measured_dynamic_stiffness(f, Hm, (lo, hi))
    k_meas, k_model = doc["measured"]["k_dyn_min_refined_N_per_m"], table1["dynamic_stiffness_N_per_m"]
    doc["measured_minus_table1_pct"] = 100.0 * (k_meas / k_model - 1.0)
    same = (drive, direction) == (table1["drive_point"], table1["direction"])
    doc["note"] = ("measured refined minimum against Table 1's model minimum, same drive point and direction" if same
                   else f"measured at {drive} in {direction}, Table 1 at {table1['drive_point']} in "
                        f"{table1['direction']}: not the same quantity")
    return doc


def write_frf_comparison(opts: HarmonicOptions, state: str, model, modes, res, pts: dict, table1: dict, stiffness_json,
                         progress=print) -> dict | None:
    # many parameters: the harmonic stage's results (model, modes, response, points, Table 1) passed on
    """Compare the state's measured FRFs with the model's and write :data:`OUTPUTS` into ``out_dir``.

    Parameters
    ----------
    opts : HarmonicOptions
        The harmonic stage's options (the band, the state's dataset).
    state : str
        Operating state.
    model, modes, res, pts
        As :func:`model_curves`.
    table1 : dict
        ``dynamic_stiffness.json``'s content (the model's Table 1 value).
    stiffness_json : path
        The harmonic stage's ``dynamic_stiffness.json``: the outputs go into its folder
        (``results/harmonic/<state>/``).

    Returns
    -------
    dict or None
        ``{"table": DataFrame, "stiffness": dict}``, or None (the files say "no measured FRF") when the
        dataset has no FRF of ``state``.
    """
    from jointid.reporting.frf_section import measured_overlay_figure, no_frf_figure
    from jointid.reporting.figures import png_bytes

    out_dir = Path(stiffness_json).parent
    measured = _measured(opts.dataset, state, progress)
    if measured is None:  # the declared outputs, saying so
        io.write_csv(pd.DataFrame(columns=COMPARE_COLUMNS), str(out_dir / OUTPUTS[0]))
        io.write_json(str(out_dir / OUTPUTS[1]), {"state": state, "available": False, "note": NO_FRF})
        with io.atomic_path(str(out_dir / OUTPUTS[2])) as tmp:
            Path(tmp).write_bytes(png_bytes(no_frf_figure(state, NO_FRF)))
        return None
    ds, drive, direction = measured
    curves, note = model_curves(model, modes, res, pts, ds, state, drive, direction)
    table = compare_table(curves)
    doc = _stiffness_doc(curves, list(opts.band_Hz), table1, drive, direction, note)
    io.write_csv(table, str(out_dir / OUTPUTS[0]))
    io.write_json(str(out_dir / OUTPUTS[1]), doc)
    with io.atomic_path(str(out_dir / OUTPUTS[2])) as tmp:
        Path(tmp).write_bytes(png_bytes(measured_overlay_figure(curves, table, state)))
    worst = table.loc[table["frac"].idxmin()]
    progress(f"harmonic[{state}]: {len(table)} measured FRF(s) against the model: FRAC {table['frac'].min():.3f}"
             f"-{table['frac'].max():.3f} (lowest {worst['point']}:{worst['direction']})"
             + (f"; measured drive-point K_min {doc['measured']['k_dyn_min_refined_N_per_mm']:.5g} N/mm, "
                f"{doc['measured_minus_table1_pct']:+.1f} % from Table 1's model" if doc["measured"] else ""))
    return {"table": table, "stiffness": doc}
