"""Measured data for the API: load a dataset folder or a UFF file, pair its modes; result records.

Helpers of :class:`jointid.api.study.Study`; the reading and checking is
:func:`jointid.data.dataset.read_dataset` and :func:`jointid.data.uff.import_uff`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from jointid.api.results import Identification
from jointid.correlate.pairing import PairedBy

__all__ = ["UFF_SUFFIXES", "identification", "load", "pairing", "write_diagnosis"]

UFF_SUFFIXES = (".uff", ".unv")
"""File suffixes read as Universal Files (every other path is a dataset folder)."""


def load(source, points: pd.DataFrame, *, state: str = "power_off", em_force_N: float | None = None):
    """A :class:`jointid.data.dataset.Dataset` from a folder or a UFF file.

    Parameters
    ----------
    source : path
        A dataset folder (``modes.csv`` [+ ``shapes.csv``, ``frf.csv``] + ``conditions.yaml``,
        docs/measurement-format.md) or a ``.uff``/``.unv`` Universal File (modes as dataset 55,
        nodes as dataset 15/2411, units from dataset 164).
    points : DataFrame
        The rig's measuring points ``point, x_m, y_m, z_m`` (m): a folder's ``shapes.csv`` points
        are checked against them, a UFF file's nodes are mapped onto them within 5 mm.
    state : str
        UFF only: the state every imported mode belongs to.
    em_force_N : float, optional
        UFF only: the vertical motor force of that state in N (default 0).

    Raises
    ------
    jointid.errors.DataError
        Every problem of the files, one line each.
    """
    from jointid.data.dataset import read_dataset
    from jointid.data.uff import import_uff

    path = Path(os.fspath(source))
    if path.suffix.lower() in UFF_SUFFIXES:
        ds, _ = import_uff(path, points, state=state, em_force_N=0.0 if em_force_N is None else em_force_N)
        return ds
    return read_dataset(path, measuring_points=points)


def pairing(d, modes, min_freq_Hz: float):
    """The :class:`jointid.correlate.pairing.Pairing` of a measured state ``d``
    (:class:`jointid.diagnosis.variants.StateData`) with model modes ``modes``
    (:class:`jointid.api.results.ModalResult`): by MAC where ``d`` has shapes; else by frequency, where
    the test's observability rule makes leaving a clearly visible mode unpaired cost its misfit (as
    rule ``verify`` pairs).  Model modes below ``min_freq_Hz`` are never paired."""
    from dataclasses import replace

    from jointid.correlate.pairing import pair_modes

    shapes, freqs = d.pairing_shapes, modes.freqs_Hz
    plain = pair_modes(d.f_meas, freqs, shapes, None if shapes is None else modes.shapes, min_freq_Hz=min_freq_Hz)
    cand = np.flatnonzero(freqs >= min_freq_Hz)
    if shapes is not None or d.rule is None or len(cand) < len(d.f_meas):
        return plain
    index = np.asarray(d.rule.pair_by_frequency(d.f_meas, freqs, d.rule.visibility(modes.shapes, freqs), cand), int)
    in_band = set(plain.unpaired_model) | set(plain.model_index[plain.model_index >= 0].tolist())
    return replace(plain, model_index=index, unpaired_model=sorted(in_band - set(index.tolist())))


def identification(state: str, names: list[str], theta0: dict, f_meas, polish: dict, paired_by: PairedBy,
                   fixed: Mapping[str, float]) -> Identification:
    """The :class:`Identification` of a polish record (:func:`jointid.identification.polish.fe_polish`);
    ``fixed``: the fixed joint parameters (``joints.fixed``, N/m^3).

    The 95 % intervals are those of ``params.json``
    (:func:`jointid.identification.polish.polish_intervals`).
    """
    from jointid.identification.polish import polish_intervals

    theta = np.asarray(polish["theta"], float)
    _, lo, hi = polish_intervals(polish)
    fixed = {k: float(v) for k, v in fixed.items()}
    return Identification(
        state=state, theta=dict(zip(names, map(float, theta))),
        ci95_low=dict(zip(names, map(float, lo))),
        ci95_high=dict(zip(names, map(float, hi))),
        theta0={k: float(theta0[k]) for k in names}, f_meas_Hz=np.asarray(f_meas, float),
        f_model_Hz=np.asarray(polish["f_fe"], float), tracking_mac=np.asarray(polish["mac"], float),
        paired_by=paired_by,
        chi2=float(polish["chi2"]), dof=int(polish["dof"]), iterations=int(polish["iterations"]),
        on_bound=tuple(polish["on_bound"]), fixed=fixed, unpaired_visible=tuple(polish["unpaired_visible"]),
        shape_chi2=float(polish.get("shape_chi2") or 0.0), shape_dof=int(polish.get("shape_dof") or 0))


def write_diagnosis(res, out_dir, dataset_name: str, config_hash: str) -> None:
    """The files rule ``diagnose`` writes for ``res`` (:func:`jointid.reporting.diagnosis_outputs.write_outputs`),
    with the time and the configuration's hash (:func:`jointid.config.config_hash`) on the page."""
    from jointid.reporting.diagnosis_outputs import write_outputs

    run = {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": config_hash}
    write_outputs(res, out_dir, dataset_name, run)
