"""Rule ``harmonic``: drive-point FRF and dynamic stiffness of one state at its identified parameters.

Reads the identified parameters, the cached model and the verify table (its pairing of measured and
FE modes), computes the response with :mod:`jointid.response.drive_point` and writes the FRF, the
dynamic stiffness summary and the modes.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from jointid import io
from jointid.geometry.points import dof_labels
from jointid.data.uff_export import write_modes_uff
from jointid.stages.frf_compare import write_frf_comparison
from jointid.stages.harmonic_damping import damping_range, state_damping, why_text
from jointid.fe.vtk import write_mesh_vtu
from jointid.response.drive_point import MODE_FACTOR, drive_vector, harmonic_response, solve_band_modes
from jointid.response.harmonic import RIGID_HZ, static_residual
from jointid.response.ranges import band_minimum

if TYPE_CHECKING:
    from jointid.config.options import HarmonicOptions
    from jointid.identification.record import IdentificationRecord


def frf_frame(res) -> pd.DataFrame:
    """FRF table of a :class:`jointid.response.drive_point.HarmonicResult`: ``freq_Hz, H_real_m_per_N,
    H_imag_m_per_N, H_abs_m_per_N, phase_deg, dynamic_stiffness_N_per_m`` (``|F/X|``)."""
    return pd.DataFrame({"freq_Hz": res.f_Hz, "H_real_m_per_N": res.H.real, "H_imag_m_per_N": res.H.imag,
                         "H_abs_m_per_N": np.abs(res.H), "phase_deg": np.degrees(np.angle(res.H)),
                         "dynamic_stiffness_N_per_m": 1.0 / np.abs(res.H)})


def run_harmonic(opts: HarmonicOptions, state: str, params_json: str, matrices: str, out_csv: str, out_json: str,
                 out_modes: str | None = None, verify_csv: str | None = None, out_points: str | None = None,
                 out_vtu: str | None = None, out_uff: str | None = None, tied_csv: str | None = None,
                 progress=print) -> dict:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """The ``harmonic`` workflow stage of one state.

    Reads the identified parameters and the cached model, writes the drive-point FRF (``out_csv``,
    columns of :func:`frf_frame`), the dynamic stiffness summary (``out_json``) and, if given, the
    modes at the measuring points (``out_modes``: ``freqs_Hz (n_modes,)``, ``shapes (n_labels,
    n_modes)``, ``labels``, ``description``, ``zeta``, ``participation``).

    Parameters
    ----------
    opts : HarmonicOptions
        The model, the band, the drive point, the damping and the state's dataset (sections ``rig, joints,
        solver, harmonic``; ``states, measurements, datasets`` name the dataset).  The damping: the identified joint damping of ``params.json`` when the data carry
        damping ratios, else the configured one (:func:`jointid.stages.harmonic_damping.state_damping`).
    state : str
        Operating state (names the dataset's damping ratios).
    params_json, matrices : str
        Identified parameters (identify stage) and the cached model (mesh stage).
    verify_csv : str, optional
        The verify stage's table; its ``fe_mode`` column pairs measured modes with FE modes (for the
        measured damping ratios, the measured order of the governing mode and the paired minimum).
    out_points : str, optional
        ``drive_points.npz`` (:func:`point_data`): the modal data of every table measuring point for
        the ranges of Table 1 (rule ``table1``).
    out_vtu, out_uff : str, optional
        The identified model's modes for ParaView (mesh with one vector field per mode,
        :func:`jointid.fe.vtk.write_mesh_vtu`) and for test software (UFF 164 + 15 + 55 at the
        measuring points, :func:`jointid.data.uff_export.write_modes_uff`).

    Returns
    -------
    dict
        The content of ``out_json``.
    """
    from jointid.fe.model import base_coefficients, load_model
    from jointid.identification.record import IdentificationRecord

    par = IdentificationRecord.read(params_json)
    theta = {n: float(v) for n, v in par.theta.items()}
    model = load_model(matrices)
    kc, mc = base_coefficients(opts.model, model, theta)
    band = list(opts.band_Hz)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res, modes, desc, damping, pts = _response(opts, state, par, model, kc, mc, band, verify_csv, progress)
    notes = [str(w.message) for w in caught]
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    io.write_csv(frf_frame(res), out_csv)
    order = _measured_order(verify_csv, res.governing)
    out = _summary(opts, state, res, desc, damping, band, theta, notes, order)
    out.update(_paired_summary(res, desc, pts["measured_order"], band))
    out["tie"] = tie_note(tied_csv, res.governing, order, float(res.freqs_Hz[res.governing]), par)
    if out["tie"]["rests_on_tie"]:
        progress(f"harmonic[{state}]: {out['tie']['note']}")
    orders = pairing_orders(pts["measured_order"], tied_csv)
    out["pairings"] = [{"pairing": name, "governing_measured_order": int(o[res.governing]) or None,
                        **_paired_summary(res, desc, o, band)} for name, o in orders.items()]
    out["damping_range"] = damping_range(opts, band, res, orders, damping)
    for p in out["pairings"]:
        progress(f"harmonic[{state}]: under the {p['pairing']} pairing: {p['status']}")
    io.write_json(out_json, out)
    if out_points:
        io.write_npz(out_points, **pts)
    _write_mode_files(model, state, res, modes, desc, out_vtu, out_uff, out_modes)
    write_frf_comparison(opts, state, model, modes, res, pts, out, out_json, progress)  # with frf.csv only
    g = res.governing
    static = out["static_stiffness_N_per_mm"]
    progress(f"harmonic[{state}]: K_dyn,min = {out['dynamic_stiffness_N_per_mm']:.5g} N/mm at "
             f"{out['f_at_min_Hz']:.1f} Hz (FE mode {g + 1}, {desc['description'][g]}), static "
             f"{'n/a' if static is None else format(static, '.5g')} N/mm; {out['status']}")
    return out


def _write_mode_files(model, state: str, res, modes, desc: pd.DataFrame, out_vtu: str | None,
                      out_uff: str | None, out_modes: str | None) -> None:
    """The identified model's modes for ParaView (``out_vtu``), for test software (``out_uff``) and at
    the measuring points (``out_modes``), each only when given (see :func:`run_harmonic`)."""
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    if out_vtu:
        write_mesh_vtu(model, out_vtu, modes.phi, res.freqs_Hz, descriptions=desc["description"].to_numpy())
    if out_uff:
        write_modes_uff(out_uff, pd.DataFrame(model.meta["points"]), labels, res.freqs_Hz, model.probe @ modes.phi,
                        damping_ratio=res.zeta, descriptions=desc["description"].to_numpy(),
                        title=f"jointid identified model, state {state}")
    if out_modes:
        io.write_npz(out_modes, freqs_Hz=res.freqs_Hz, shapes=model.probe @ modes.phi, labels=np.array(labels),
                     description=desc["description"].to_numpy().astype(str), zeta=res.zeta,
                     participation=res.participation)


def status_text(fe_mode: int, freq_Hz: float, description: str, measured_order) -> str:
    """Table 1's status of a state: ``identified`` when the mode that sets the band minimum is paired
    with a measured mode, else why not."""
    if measured_order:
        return "identified"
    return (f"not identified: the governing mode (FE mode {fe_mode}, {freq_Hz:.1f} Hz, {description}) has no "
            "measured partner")


def tie_note(tied_csv: str | None, g: int, order: int | None, freq_Hz: float,
             par: "IdentificationRecord | None" = None) -> dict:
    """Whether Table 1's status rests on the choice among exactly tied pairings: ``rests_on_tie`` is
    true when a pairing fitting exactly as well as the chosen one pairs the governing FE mode ``g``
    (0-based) where the chosen one does not, or the reverse; ``note`` says which, in words, and which
    rule chose (``rule``: ``params.json``'s ``tie_rule``, given ``par``; "" without one)."""
    tie = None if par is None else par.tie_rule
    rule = "" if tie is None else tie.rule
    out = {"rests_on_tie": False, "note": "", "tied_pairings": 0, "rule": rule}
    if not tied_csv:
        return out
    tied = io.read_csv(tied_csv)
    out["tied_pairings"] = int(tied["alternative"].nunique()) if len(tied) else 0
    for a, grp in tied.groupby("alternative"):
        hit = grp.loc[grp["fe_mode"] == g + 1, "order"]
        alt = int(hit.iloc[0]) if len(hit) else None
        if bool(alt) != bool(order):
            out["rests_on_tie"] = True
            out["note"] = (f"an exactly tied pairing pairs the governing mode (FE mode {g + 1}, {freq_Hz:.1f} Hz) "
                           f"with measured mode {alt}" if alt else
                           f"an exactly tied pairing leaves the governing mode (FE mode {g + 1}, {freq_Hz:.1f} Hz) "
                           f"without the measured partner {order} it has here") + _chosen_by(rule, par, int(a))
            break
    return out


def _chosen_by(rule: str, par: "IdentificationRecord | None", alternative: int) -> str:
    """The end of a tie note: which rule chose between the tied pairings, and for resolvability why
    the tied ``alternative`` (1-based, in the order of ``tied_pairings.csv``) lost."""
    from jointid.identification.record import TieChoice
    from jointid.identification.ties import tied_alternatives

    if par is None or par.tie_rule is None or par.tie_rule.choice is not TieChoice.RESOLVABILITY:
        return (f": frequencies alone cannot choose between them (chosen by {rule or 'the first found'}), "
                "measured mode shapes would")
    cols = None
    alts = tied_alternatives(par.pairing_candidates, list(par.pairing_columns))
    if 1 <= alternative <= len(alts):
        cols = alts[alternative - 1]
    lost = par.tie_rule.tied_pairing(cols)
    out = ": the fit cannot choose between them; the resolvability rule did"
    if lost:
        far = [m for m in lost["unpaired_visible"] if m["hides"] is False]
        out += (" (that pairing leaves unpaired " + "; ".join(
            f"{m['freq_Hz']:.0f} Hz{' (' + m['state'] + ')' if 'state' in m else ''}, {m['offset_pct']:+.1f} % from "
            f"measured mode {m['measured_order']} ({m['measured_Hz']:.0f} Hz), outside its half-power band "
            f"±{100 * m['damping_ratio']:.1f} %" for m in far) + ": a peak the test would have shown on its own)")
    return out + "; measured mode shapes would confirm it"


def pairing_orders(chosen_order, tied_csv: str | None) -> dict:
    """Per admissible pairing (``"chosen"``, then ``"tied 1"``, ``"tied 2"``, ... as
    ``tied_pairings.csv`` numbers them), the order of the measured mode paired with each FE mode
    (0 = none), as ``chosen_order`` (the verify table's) gives it for the chosen pairing.  The response
    itself is the chosen pairing's: tied pairings share the parameters, but measured damping ratios
    (when the dataset has them) stay on the chosen pairing's partners."""
    chosen_order = np.asarray(chosen_order, dtype=int)
    out = {"chosen": chosen_order}
    if tied_csv:
        tied = io.read_csv(tied_csv)
        for a, grp in tied.groupby("alternative"):
            o = np.zeros(chosen_order.size, dtype=int)
            for order, fe in zip(grp["order"], grp["fe_mode"]):
                if 1 <= int(fe) <= o.size:
                    o[int(fe) - 1] = int(order)
            out[f"tied {int(a)}"] = o
    return out


def _paired_summary(res, desc, measured_order, band) -> dict:
    """``status``, ``paired_minimum`` (the lowest resonance peak of a paired mode, or None) and the
    drive patch for ``dynamic_stiffness.json``."""
    g = res.governing
    order = np.asarray(measured_order, dtype=int)
    m = band_minimum(band, res.freqs_Hz, res.zeta, np.zeros(res.zeta.size), res.participation,
                     paired=order > 0, f_Hz=res.f_Hz, H=res.H)
    paired = None
    if m["mode_paired"] is not None:
        r = m["mode_paired"]
        paired = {"dynamic_stiffness_N_per_m": m["k_paired_N_per_m"],
                  "dynamic_stiffness_N_per_mm": m["k_paired_N_per_m"] * 1e-3, "f_at_min_Hz": m["f_paired_Hz"],
                  "fe_mode": r + 1, "freq_Hz": float(res.freqs_Hz[r]), "description": str(desc["description"][r]),
                  "measured_order": int(order[r]), "damping_ratio": float(res.zeta[r]),
                  "joint_share": float(desc["strain_joints"][r]) if "strain_joints" in desc else None}
    return {"status": status_text(g + 1, float(res.freqs_Hz[g]), str(desc["description"][g]), int(order[g])),
            "paired_minimum": paired}


def _measured_order(verify_csv: str | None, g: int) -> int | None:
    """Order of the measured mode paired with FE mode ``g`` (0-based) in the verify table, if any."""
    if not verify_csv:
        return None
    ver = io.read_csv(verify_csv)
    hit = ver.index[ver["fe_mode"] == g + 1]
    return int(ver.loc[hit[0], "order"]) if len(hit) else None


def _summary(opts, state, res, desc, damping, band, theta, notes, order) -> dict:
    # many parameters: the parts of dynamic_stiffness.json that run_harmonic computed
    """The content of ``dynamic_stiffness.json``."""
    g = res.governing
    k_r = (2 * np.pi * res.freqs_Hz[g]) ** 2 / res.participation[g] ** 2
    dyn = res.dynamic
    R, H0 = res.residual_flexibility_m_per_N, res.static_receptance_m_per_N
    return {
        "state": state,
        "drive_point": opts.drive_point, "direction": opts.direction,
        "patch_diameter_m": opts.patch_diameter_m,
        "band_Hz": band,
        "dynamic_stiffness_N_per_m": dyn["k_dyn_min_N_per_m"],
        "dynamic_stiffness_N_per_mm": dyn["k_dyn_min_N_per_m"] * 1e-3,
        "f_at_min_Hz": dyn["f_at_min_Hz"],
        "static_stiffness_N_per_m": dyn["k_static_N_per_m"],
        "static_stiffness_N_per_mm": None if dyn["k_static_N_per_m"] is None else dyn["k_static_N_per_m"] * 1e-3,
        "governing_mode": {
            "fe_mode": g + 1, "freq_Hz": float(res.freqs_Hz[g]), "description": str(desc["description"][g]),
            "damping_ratio": float(res.zeta[g]), "measured_order": order,
            "modal_stiffness_N_per_m": float(k_r),
            "two_zeta_k_N_per_m": float(2 * res.zeta[g] * k_r),
            "strain_joints": float(desc["strain_joints"][g])},
        "damping": {"config": damping["config"], "measured": damping["measured"],
                    "per_mode": [{"fe_mode": i + 1, "freq_Hz": float(f), "damping_ratio": float(z), "source": src}
                                 for i, (f, z, src) in enumerate(zip(res.freqs_Hz, res.zeta, res.damping_source))],
                    "why": why_text(damping), "source": damping["kind"], "text": damping["text"]},
        "modes": {"n_modes": int(res.freqs_Hz.size), "highest_Hz": float(res.freqs_Hz[-1]),
                  "target_Hz": MODE_FACTOR * band[1]},
        "residual": {"used": R is not None, "flexibility_m_per_N": R, "static_receptance_m_per_N": H0,
                     "note": res.residual_note},
        "parameters_N_per_m3": theta,
        "warnings": notes,
        "n_freq": int(res.f_Hz.size),
    }


def _response(opts, state, par, model, kc, mc, band, verify_csv, progress):
    # many parameters: the computing part of run_harmonic, with the inputs it read
    """Modes, residual, damping and FRF of one state (the computing part of :func:`run_harmonic`), and
    the modal data of every table point (:func:`point_data`)."""
    import scipy.sparse as sp

    from jointid.fe.describe import describe_modes
    from jointid.fe.modal import free_dofs, release_model_pages, restrict

    s = opts.model.solver
    K, M = model.K(kc), model.M(mc)
    release_model_pages(model)  # assembled: the model file's pages are not needed while factorising
    modes, shifted = solve_band_modes(K, M, band[1], fixed=model.fixed, n_start=max(int(s.n_modes), 12),
                                      shift_Hz=s.shift_Hz, backend=s.backend, progress=progress,
                                      keep_factor=True, ordering=model.ordering)
    direction = opts.direction
    try:
        names, P = drive_patches(model, opts.drive_point, direction, opts.patch_diameter_m)
        K_free = restrict(sp.csr_matrix(K), free_dofs(K.shape[0], model.fixed))  # once for the patches' loads
        resid = [static_residual(K, np.asarray(P[k].toarray()).ravel(), modes.phi, modes.freqs_Hz, fixed=model.fixed,
                                 backend=s.backend, shifted=shifted, K_free=K_free) for k in range(len(names))]
    finally:
        shifted.free_memory()
    k0 = names.index(opts.drive_point)
    p = np.asarray(P[k0].toarray()).ravel()
    R, H0, note = resid[k0]
    desc = describe_modes(model, modes.phi, kc, mc)
    progress(f"harmonic[{state}]: {note}")
    share = np.where(modes.freqs_Hz >= RIGID_HZ, desc["strain_joints"].to_numpy(float), 0.0)
    damping = state_damping(opts, state, par.joint_damping, model, modes, kc, share, verify_csv)
    zeta = damping["zeta"]
    progress(f"harmonic[{state}]: damping {damping['text']}")
    res = harmonic_response(modes, p, zeta, band, n_freq=opts.n_freq, residual=R, static_receptance=H0)
    res.damping_source, res.residual_note = damping["source"], note
    pts = point_data(names, P @ modes.phi, resid, modes.freqs_Hz, share, _measured_orders(verify_csv, modes.freqs_Hz.size),
                     desc, zeta, direction, opts.patch_diameter_m)
    return res, modes, desc, damping, pts


def drive_patches(model, drive_point: str, direction: str, diameter_m: float):
    """Load / response vectors (a hammer-tip patch of ``diameter_m``, :func:`jointid.fe.patch.patch_probe`)
    in ``direction`` at every table measuring point and at the drive point: ``(names, P)`` with ``P``
    of shape ``(len(names), n_dofs)``."""
    from jointid.fe.patch import patch_probe

    drive_vector(model, drive_point, direction)  # a clear error for an unknown point or direction
    table = pd.DataFrame(model.meta["points"])
    names = [str(p) for p in table.loc[table["part"] == "table", "point"]]
    if drive_point not in names:
        names.append(drive_point)
    rows = patch_probe(model, names, diameter_m)
    return names, rows[np.arange(len(names)) * 3 + "xyz".index(direction)]


def _measured_orders(verify_csv: str | None, n_modes: int) -> np.ndarray:
    """Per FE mode (0-based), the order of the measured mode paired with it in the verify table; 0 = none."""
    out = np.zeros(n_modes, dtype=int)
    if verify_csv:
        ver = io.read_csv(verify_csv)
        for order, fe in zip(ver["order"], ver["fe_mode"]):
            if 1 <= int(fe) <= n_modes:
                out[int(fe) - 1] = int(order)
    return out


def point_data(names, pphi, resid, freqs_Hz, share, measured_order, desc, zeta, direction, diameter_m) -> dict:
    # many parameters: one array per column of drive_points.npz
    """The content of ``drive_points.npz``: ``points (n_pts,)``, ``pphi (n_pts, n_modes)`` (patch
    participation ``p^T phi_r``, m/sqrt(kg) per N), ``residual_m_per_N`` and ``static_receptance_m_per_N``
    ``(n_pts,)`` (NaN where K is singular), ``freqs_Hz, joint_share, measured_order`` (0 = unpaired),
    ``description, zeta`` (the configured damping) ``(n_modes,)``, ``direction``, ``patch_diameter_m``."""
    nan = lambda v: np.nan if v is None else float(v)  # noqa: E731
    return {"points": np.array(names), "pphi": np.asarray(pphi), "residual_m_per_N": np.array([nan(r[0]) for r in resid]),
            "static_receptance_m_per_N": np.array([nan(r[1]) for r in resid]), "freqs_Hz": np.asarray(freqs_Hz),
            "joint_share": np.asarray(share), "measured_order": np.asarray(measured_order),
            "description": desc["description"].to_numpy().astype(str), "zeta": np.asarray(zeta),
            "direction": np.array(direction), "patch_diameter_m": np.array(diameter_m)}
