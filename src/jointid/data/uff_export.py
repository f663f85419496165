"""Universal File Format export: the model's modes at the measuring points (datasets 164, 15, 55) and
receptance FRFs (datasets 164, 15, 58).

The file holds the units (dataset 164, SI: m, N, s), the measuring points as nodes (dataset 15,
node ``k`` = the k-th row of ``measuring_points.csv``, coordinates in m in the model axes: X
lateral, Y vertical, Z feed) and one real normal mode per dataset 55 (analysis type 2, x, y, z per
node, mass-normalised, frequency in Hz and the modal damping ratio of the harmonic stage).  Test
software that reads UFF (LMS Test.Lab, pyuff-based tools, MEscope) animates and correlates it;
:func:`jointid.data.uff.import_uff` reads it back.

:func:`write_frf_uff` writes FRFs (a dataset's ``frf.csv`` rows of one state) as dataset 58, function type 4,
displacement over force (m/N), with uneven abscissa, in the binary form (58b): the ASCII form holds the
frequencies to 6 significant digits (fields E13.5) and the values to 12, the binary one holds both as
IEEE doubles, so the FRFs read back exactly.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.io import atomic_path

__all__ = ["write_frf_uff", "write_modes_uff"]


def write_modes_uff(path, points: pd.DataFrame, labels, freqs_Hz, shapes, *, damping_ratio=None,
                    descriptions=None, title: str = "jointid model modes") -> None:
    """Write the modes at the measuring points as UFF 164 + 15 + 55 (atomically).

    Parameters
    ----------
    path : path
        The ``.uff`` file to write.
    points : DataFrame
        ``point, x_m, y_m, z_m`` (the measuring points; node k is row k, 1-based).
    labels : sequence of str
        ``"<point>:<direction>"`` of each row of ``shapes``.
    freqs_Hz : (n_modes,) array
    shapes : (n_labels, n_modes) array
        Mode shapes at ``labels`` (mass-normalised, m/sqrt(kg)).
    damping_ratio : (n_modes,) array, optional
        Modal viscous damping ratios (written as R8 F3).
    descriptions : sequence of str, optional
        One line per mode (written as the dataset's ID line 4).
    """
    import pyuff  # noqa: PLC0415  (import on use: pyuff is only needed here)

    names = [str(p) for p in points["point"]]
    node = {p: k + 1 for k, p in enumerate(names)}
    xyz = points[["x_m", "y_m", "z_m"]].to_numpy(float)
    freqs_Hz = np.asarray(freqs_Hz, float)
    shapes = np.asarray(shapes, float)
    zeta = np.zeros(len(freqs_Hz)) if damping_ratio is None else np.asarray(damping_ratio, float)
    rows = {lab: i for i, lab in enumerate(labels)}
    sets = [pyuff.prepare_164(units_code=1, units_description="SI - meter, newton", temp_mode=2,
                              length=1.0, force=1.0, temp=1.0, temp_offset=273.15),
            pyuff.prepare_15(node_nums=list(node.values()), def_cs=[0] * len(names), disp_cs=[0] * len(names),
                             color=[1] * len(names), x=list(xyz[:, 0]), y=list(xyz[:, 1]), z=list(xyz[:, 2]))]
    for j, f in enumerate(freqs_Hz):
        comp = []
        for d in "xyz":
            comp.append(np.array([shapes[rows[f"{p}:{d}"], j] if f"{p}:{d}" in rows else 0.0 for p in names]))
        desc = "" if descriptions is None else str(descriptions[j])[:80]
        sets.append(pyuff.prepare_55(
            id1=title[:80], id2=f"mode {j + 1} at {f:.3f} Hz", id3="mass-normalised, model axes X lateral "
            "Y vertical Z feed", id4=desc or "NONE", id5="NONE", model_type=1, analysis_type=2, data_ch=2,
            spec_data_type=8, data_type=2, n_data_per_node=3, r1=comp[0], r2=comp[1], r3=comp[2],
            node_nums=list(node.values()), load_case=1, mode_n=j + 1, modal_m=1.0, freq=float(f),
            modal_damp_vis=float(zeta[j]), modal_damp_his=0.0))
    with atomic_path(path) as tmp:
        _write_sets(pyuff.UFF(str(tmp)), sets)


def write_frf_uff(path, points: pd.DataFrame, frf: pd.DataFrame, *, drive_point: str, drive_direction: str,
                  title: str = "jointid FRFs", binary: bool = True) -> None:
    """Write receptance FRFs as UFF 164 + 15 + 58 (atomically).

    Parameters
    ----------
    path : path
        The ``.uff`` file to write.
    points : DataFrame
        ``point, x_m, y_m, z_m`` (node k is row k, 1-based).
    frf : DataFrame
        ``point, direction, freq_Hz, re, im`` of one excitation (receptance in m/N, frequencies in Hz);
        one dataset 58 per ``(point, direction)``, lines in order of frequency.
    drive_point, drive_direction : str
        The excitation (reference node and direction of every FRF).
    title : str
        ID line 1 of each dataset 58.
    binary : bool
        Binary 58b (exact doubles, the default) or ASCII (frequencies to 6 significant digits).
    """
    import pyuff  # noqa: PLC0415  (import on use: pyuff is only needed here)

    names = [str(p) for p in points["point"]]
    node = {p: k + 1 for k, p in enumerate(names)}
    xyz = points[["x_m", "y_m", "z_m"]].to_numpy(float)
    axis = {d: i + 1 for i, d in enumerate("xyz")}
    sets = [pyuff.prepare_164(units_code=1, units_description="SI - meter, newton", temp_mode=2,
                              length=1.0, force=1.0, temp=1.0, temp_offset=273.15),
            pyuff.prepare_15(node_nums=list(node.values()), def_cs=[0] * len(names), disp_cs=[0] * len(names),
                             color=[1] * len(names), x=list(xyz[:, 0]), y=list(xyz[:, 1]), z=list(xyz[:, 2]))]
    for (point, d), g in frf.groupby(["point", "direction"], sort=False):
        g = g.sort_values("freq_Hz")
        sets.append(pyuff.prepare_58(
            binary=int(bool(binary)), id1=title[:80], id2=f"receptance {point}:{d} / {drive_point}:{drive_direction}",
            id3="m/N, model axes X lateral Y vertical Z feed", func_type=4, rsp_node=node[str(point)], rsp_dir=axis[d],
            ref_node=node[str(drive_point)], ref_dir=axis[drive_direction], rsp_ent_name="response",
            ref_ent_name="drive", data=g["re"].to_numpy(float) + 1j * g["im"].to_numpy(float),
            x=g["freq_Hz"].to_numpy(float), ord_data_type=6, abscissa_spacing=0, abscissa_spec_data_type=18,
            ordinate_spec_data_type=8, orddenom_spec_data_type=13))
    with atomic_path(path) as tmp:
        _write_sets(pyuff.UFF(str(tmp)), sets)


def _write_sets(uff, sets) -> None:
    """``uff.write_sets(sets, mode="overwrite")``.  pyuff 2.4's ASCII writer of data set 58 leaves its file to
    the garbage collector (it never calls close); the file is closed, and its data flushed, when the call
    returns, before the atomic rename.  The ResourceWarning that close raises is pyuff's, and is silenced here."""
    import gc
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        uff.write_sets(sets, mode="overwrite")
        gc.collect()  # the writer's file is closed here, inside the filter
