"""Rules ``modal``/``modal_zoom`` (the DOE points' modes: all in one job on one reduced basis with
``solver.method: reduced``, one job per point otherwise), ``gather_modal``/``gather_zoom``
and ``rom`` (the parametric reduced-order model of ``solver.method: rom``).

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`): the
modal fan-out is the workflow's largest, and each job loads only what its solve uses.
"""

from __future__ import annotations

import numpy as np

from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.typed import ModelSpec


def run_modal(spec: ModelSpec, matrices: str, theta: dict[str, float], out_npz: str, rom: str | None = None) -> None:
    """Modes at one DOE point -> ``out_npz`` (freqs_Hz, shapes, labels, description, strain_joints, theta).

    ``solver.method``: ``full`` solves the FE model; ``rom`` evaluates the reduced-order
    model ``rom`` (written by :func:`run_rom`) and expands its modes to full DOF vectors for the
    mode descriptions.  Both write the same arrays.  ``spec``: the model's :class:`~jointid.config.typed.ModelSpec`.
    """
    from jointid.fe.model import load_model

    io.write_npz(out_npz, **point_modes(spec, load_model(matrices), theta, rom))


def point_modes(spec: ModelSpec, model, theta: dict[str, float], rom: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of one DOE point's modal file (:func:`point_arrays`): a full solve of ``model``, or with
    ``solver.method: rom`` the reduced-order model ``rom``."""
    if spec.solver.method == "rom":
        freqs, shapes, desc = _rom_point(spec, model, theta, rom)
    else:
        from jointid.identification.polish import solve_point

        freqs, shapes, desc, _ = solve_point(spec, model, theta)
    log("modal: " + ", ".join(f"{f:.1f}" for f in freqs) + " Hz")
    return point_arrays(freqs, shapes, desc, _labels(model), theta)


def _labels(model) -> np.ndarray:
    import pandas as pd

    from jointid.geometry.points import dof_labels

    return np.array(dof_labels(pd.DataFrame(model.meta["points"])))


def point_arrays(freqs, shapes, desc, labels, theta: dict[str, float], **extra) -> dict[str, np.ndarray]:
    """The arrays of one DOE point's modal file (those :func:`gathered` reads, and ``extra``)."""
    return dict(freqs_Hz=freqs, shapes=shapes, labels=labels, description=desc["description"].to_numpy().astype(str),
                strain_joints=desc["strain_joints"].to_numpy(), theta_names=np.array(list(theta)),
                theta=np.array(list(theta.values())), **extra)


def run_modal_points(spec: ModelSpec, matrices: str, sheet_csv: str, out_npzs: list[str]) -> None:
    """``solver.method: reduced``: the modes of every point of ``sheet_csv`` in one job, on one reduced
    basis certified point by point (:mod:`jointid.identification.doe_modes`) -> one file per point
    (``out_npzs``, named ``<point>.npz``; the arrays of :func:`run_modal` and the point's
    certificate: ``residual_error``, ``basis_size``)."""
    import os
    import time

    from jointid.fe.model import load_model

    paths = {os.path.splitext(os.path.basename(p))[0]: p for p in out_npzs}
    sheet = io.read_csv(sheet_csv)
    if sorted(sheet["point"]) != sorted(paths):
        from jointid.errors import DataError

        raise DataError(f"modal: the outputs {', '.join(sorted(paths))} are not the points of {sheet_csv} "
                        f"({', '.join(sheet['point'])}) — rerun rule doe")
    t0 = time.time()
    model = load_model(matrices)
    for point, arrays in doe_modes(spec, model, sheet):
        io.write_npz(paths[point], **arrays)
    log(f"modal: {len(paths)} points on one reduced basis ({model.n_dofs} DOFs) in {time.time() - t0:.1f} s")


def doe_modes(spec: ModelSpec, model, sheet):
    """The modal files' arrays (:func:`point_arrays`) of every point of a DOE sample sheet, point by point:
    ``(point, arrays)``.  ``solver.method: reduced``: on one reduced basis certified point by point
    (:mod:`jointid.identification.doe_modes`; the arrays hold the point's ``residual_error`` and
    ``basis_size``); ``full``: a full solve each (:func:`point_modes`)."""
    names = spec.joints.names
    points = list(sheet["point"])
    thetas = [{n: float(v) for n, v in zip(names, row)} for row in sheet[names].to_numpy(float)]
    if spec.solver.method != "reduced":
        for point, theta in zip(points, thetas):
            yield point, point_modes(spec, model, theta)
        return
    from jointid.identification.doe_modes import solve_points
    from jointid.progress import Steps

    labels, steps = _labels(model), Steps(len(points))
    for point, theta, res in zip(points, thetas, solve_points(spec, model, thetas, log=log)):
        log(f"modal {point} {steps.done()}: " + ", ".join(f"{f:.1f}" for f in res.freqs_Hz) +
            f" Hz (basis {res.basis_size} vectors, estimated eigenvalue error {res.error:.1e})")
        yield point, point_arrays(res.freqs_Hz, res.shapes, res.description, labels, theta,
                                  residual_error=np.float64(res.error), basis_size=np.int64(res.basis_size))


def _rom_point(spec: ModelSpec, model, theta: dict[str, float], rom: str | None):
    """``(freqs_Hz, shapes at the measuring points, description)`` of the ROM file ``rom`` at ``theta``."""
    from jointid.errors import ConfigError
    from jointid.fe.describe import describe_modes
    from jointid.fe.model import base_coefficients
    from jointid.identification.rom import full_modes, load_rom

    if not rom:
        raise ConfigError("solver.method: rom needs the reduced-order model (rule rom, "
                          "results/rom/rom.npz) — build it with run_rom, or set solver.method: full")
    reduced = load_rom(rom)
    kc, mc = base_coefficients(spec, model, theta)
    modes = full_modes(reduced, kc, mc, spec.solver.n_modes)
    return modes.freqs_Hz, model.probe @ modes.phi, describe_modes(model, modes.phi, kc, mc)


def run_rom(spec: ModelSpec, matrices: str, sheet_csv: str, out_npz: str, out_json: str) -> dict:
    """Build the parametric reduced-order model once (``solver.method: rom``) with error control.

    Training: a full solve at the centre of the joint-parameter box (``solver.n_modes`` + 2 modes),
    then one block inverse iteration from the current Ritz vectors at each corner (one factorisation
    each, no Lanczos run; :func:`jointid.identification.rom_build.build_rom`).  Error control: candidate points (random
    interior ones and every point of the DOE sheet) are ranked by the residual indicator; the worst
    are solved in full, and the basis is
    enriched until the relative frequency error of every tracked mode (at or above
    ``solver.min_freq_Hz``) is at most ``solver.rom_tolerance``.  Writes the ROM with its basis
    (``out_npz``, :func:`jointid.identification.rom.load_rom`) and a summary (``out_json``: tolerance, achieved
    error, basis size, verification rounds); returns the summary.

    Raises
    ------
    ModelError
        If the tolerance is not met after the enrichment rounds.
    """
    import warnings

    import pandas as pd

    from jointid.errors import ModelError, NumericalWarning
    from jointid.fe.model import load_model
    from jointid.identification.rom_build import RomOptions, build_rom

    s = spec.solver
    tol = float(s.rom_tolerance)
    model = load_model(matrices)
    sheet = io.read_csv(sheet_csv)
    doe_x = sheet[[f"x_{n}" for n in spec.joints.names]].to_numpy(float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)  # not verified: raised as an error below
        rom = build_rom(model, spec, "corners", RomOptions(n_modes=s.n_modes, tol=tol),
                        candidates=doe_x, progress=log)
    rep = rom.report
    n_inverse = sum(1 for t in rep["training"] if t.get("how", "full solve") != "full solve")
    n_full = len(rep["training"]) - n_inverse + sum(len(r["points"]) for r in rep["rounds"])
    summary = {"n_dofs": int(model.n_dofs), "n_modes": rep["n_modes"], "n_train_modes": rep["n_train_modes"],
               "min_freq_Hz": float(s.min_freq_Hz), "tolerance": tol, "max_error": rep["max_error"],
               "verified": rep["verified"], "basis_size": rom.size, "n_full_solves": n_full,
               "n_inverse_iteration_points": n_inverse,
               "n_training_points": len(rep["training"]), "n_doe_candidates": int(len(doe_x)),
               "rounds": [{"round": r["round"], "basis_size": r["r"], "max_error": r["max_error"],
                           "added": r.get("added", 0),
                           "points": [{"theta": p["theta"], "max_error": p["max_error"]} for p in r["points"]]}
                          for r in rep["rounds"]],
               "coeff_range": rom.coeff_range}
    if not rep["verified"]:
        raise ModelError(f"rom: relative frequency error {rep['max_error']:.2e} at the verification points is "
                         f"above solver.rom_tolerance = {tol:.1e} after {len(rep['rounds'])} enrichment rounds "
                         f"(basis size {rom.size}) — raise solver.rom_tolerance, narrow joints.parameters, "
                         "or use solver.method: full")
    rom.save(out_npz)
    io.write_json(out_json, summary)
    log(f"rom: basis {rom.size} vectors from {n_full} full solves and {n_inverse} inverse-iteration points "
        f"({model.n_dofs} DOFs); max relative "
        f"frequency error at the verification points {rep['max_error']:.2e} <= {tol:.1e} -> {out_npz}")
    return summary


def run_gather(sheet_csv: str, npz_paths: list[str], out_csv: str, out_npz: str) -> None:
    """Rules ``gather_modal``/``gather_zoom``: per-point modal results -> one long table and one array file."""
    table, arrays = gathered(io.read_csv(sheet_csv), [io.load_npz(p) for p in npz_paths])
    io.write_csv(table, out_csv)
    io.write_npz(out_npz, **arrays)
    log(f"gather: {len(npz_paths)} points -> {out_csv}")


def gathered(sheet, points: list[dict[str, np.ndarray]]):
    """The DOE points' modes (their files' arrays, :func:`point_arrays`, in the sheet's order) in one long table
    (``point, mode, freq_Hz, description, strain_joints``) and one set of arrays (``points, freqs_Hz, shapes,
    labels, descriptions``): ``(table, arrays)``."""
    import pandas as pd

    rows, freqs, shapes, descr = [], [], [], []
    for point, z in zip(sheet["point"], points):
        freqs.append(z["freqs_Hz"])
        shapes.append(z["shapes"])
        descr.append(z["description"])
        for j, f in enumerate(z["freqs_Hz"]):
            rows.append({"point": point, "mode": j + 1, "freq_Hz": float(f),
                         "description": str(z["description"][j]), "strain_joints": float(z["strain_joints"][j])})
    arrays = dict(points=sheet["point"].to_numpy().astype(str), freqs_Hz=np.array(freqs), shapes=np.array(shapes),
                  labels=points[0]["labels"], descriptions=np.array(descr))
    return pd.DataFrame(rows), arrays
