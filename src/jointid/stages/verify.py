"""Rule ``verify``: a full FE re-solve at the identified parameters gives the tables' frequencies.

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    import pandas as pd

    from jointid.config.typed import ModelSpec
    from jointid.identification.optimum_modes import OptimumModes
    from jointid.identification.record import IdentificationRecord



def visibility_rule(par: "IdentificationRecord", labels: list[str]):
    """The identification's observability rule (its ``params.json`` record), or None without one."""
    return None if par.observability is None else par.observability.rule(labels)


def _pairing(min_freq_Hz: float, par: "IdentificationRecord", doc: dict, f_all, shapes, rule=None):
    """``(FE mode index, MAC to the tracked mode)`` of each measured mode at the identified parameters (FE modes
    from ``min_freq_Hz`` up)."""
    from jointid.correlate.pairing import PairedBy
    from jointid.identification.updating import verify_pairing

    f_meas = np.asarray(par.f_meas_Hz)
    if par.paired_by is PairedBy.FREQUENCY:  # the polish's rule: re-paired by frequency at its optimum
        from jointid.correlate.mac import mac
        from jointid.correlate.pairing import pair_by_frequency

        cand = np.flatnonzero(f_all >= min_freq_Hz)
        if rule is None:
            index = cand[pair_by_frequency(f_meas, f_all[cand])]
        else:
            index = rule.pair_by_frequency(f_meas, f_all, rule.visibility(shapes, f_all), cand)
        ref = np.asarray(doc["ref_shapes"])[:, np.asarray(par.pairing_columns)]
        macs = np.array([float(mac(ref[:, i], shapes[:, j])[0, 0]) for i, j in enumerate(index)])
    else:
        index, macs = verify_pairing(doc, np.asarray(par.pairing_columns), shapes)
    return index, macs


def tied_pairings(par: "IdentificationRecord", doc: dict, shapes) -> "pd.DataFrame":
    """The FE modes that the pairings fitting exactly as well as the chosen one pair with each measured
    mode (columns ``alternative, order, fe_mode``; ``fe_mode`` 0 where none): the tracked modes of each
    such pairing (``params.json``'s ``joint_pairing``, frequency-only states paired alike) found among
    the FE modes by MAC, as for the chosen pairing.  Empty where no pairing ties with the chosen one,
    or the pairing was not shared by frequency."""
    import pandas as pd

    from jointid.correlate.pairing import PairedBy
    from jointid.identification.ties import tied_alternatives
    from jointid.identification.updating import verify_pairing

    rows = []
    if par.paired_by is PairedBy.FREQUENCY_SHARED and par.pairing_candidates:
        for a, cols in enumerate(tied_alternatives(par.pairing_candidates, list(par.pairing_columns)), start=1):
            index, _ = verify_pairing(doc, np.asarray(cols), shapes)
            rows += [{"alternative": a, "order": i + 1, "fe_mode": int(j) + 1} for i, j in enumerate(index)]
    return pd.DataFrame(rows, columns=["alternative", "order", "fe_mode"])


def _recorded_limit(rec: dict, theta: dict, names: list[str], freqs, shapes):
    """The base mesh's modes scaled by a recorded :class:`jointid.fe.extrapolate.FrequencyCorrection`,
    as an object with the :class:`jointid.fe.extrapolate.EdgeLimit` fields verify reads (``limit_Hz``,
    ``factor``, ``ratio``, ``status``)."""
    from types import SimpleNamespace

    from jointid.fe.extrapolate import FrequencyCorrection

    c, _ = FrequencyCorrection.from_record(rec).factors(shapes, np.array([theta[n] for n in names]))
    n = len(freqs)
    return SimpleNamespace(limit_Hz=np.asarray(freqs) * c, factor=c, ratio=np.full(n, np.nan),
                           status=["recorded" if abs(x - 1) > 0 else "no partner" for x in c])


def _extrapolated(spec, state, par, model, freqs, shapes, edge_matrices):
    """The mesh-extrapolated modes at the identified parameters (see :func:`verify`; ``spec``: the model's
    :class:`~jointid.config.typed.ModelSpec`), or None without extrapolation."""
    from jointid.fe.model import load_model
    from jointid.identification.polish import edge_limit_at, model_sizes

    correction = par.correction_record
    if correction:  # the identification's last factors, carried to these parameters to first order
        log(f"verify[{state}]: mesh extrapolation: the identification's factors (taken at its previous "
            "optimum, to first order), not re-solved on the edge levels")
        return _recorded_limit(correction, par.theta, correction["names"], freqs, shapes)
    if edge_matrices:
        return edge_limit_at(spec, [model, *(partial(load_model, p) for p in edge_matrices)], par.theta,
                             log=lambda m: log(f"verify[{state}]: {m}"), base=(freqs, shapes),
                             sizes=[model.n_dofs, *model_sizes(edge_matrices)])
    return None


def write_certificate(state: str, par: "IdentificationRecord", modes, out_json: str | None) -> dict:
    """Write the :func:`certificate` of the full solve at the identified parameters to ``out_json``; returns it."""
    rec = certificate(state, par, modes)
    if out_json:
        io.write_json(out_json, rec)
    return rec


def certificate(state: str, par: "IdentificationRecord", modes) -> dict:
    """Log the certificate of the full solve at the identified parameters (its residual and Sturm
    count, :func:`jointid.fe.certificate.full_certificate`) and return its record, beside the
    identification's (``params.json``: ``fe_polish.certificate``, the reduced solver's)."""
    from jointid.fe.certificate import full_certificate

    cert = full_certificate(modes)
    log(f"verify[{state}]: {cert.describe()}")
    return {"state": state, "parameters": par.theta, "verify": cert.to_record(),
            "identify": None if par.fe_polish is None else par.fe_polish.certificate}


def run_verify(spec: ModelSpec, state: str, params_json: str, surface_json: str, matrices: str, out_csv: str,
               edge_matrices: list[str] | None = None, unpaired_csv: str | None = None,
               tied_csv: str | None = None, certificate_json: str | None = None,
               modes_npz: str | None = None) -> None:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rule ``verify``: :func:`verify` on the rule's files -> ``out_csv`` (``verify.csv``), ``unpaired_csv``,
    ``tied_csv``, ``certificate_json`` and ``modes_npz`` (the modes the mesh check needs,
    :class:`jointid.identification.optimum_modes.OptimumModes`)."""
    from jointid.fe.model import load_model
    from jointid.identification.record import IdentificationRecord

    res = verify(spec, state, IdentificationRecord.read(params_json), io.read_json(surface_json),
                 load_model(matrices), edge_matrices)
    if certificate_json:
        io.write_json(certificate_json, res.certificate)
    io.write_csv(res.table, out_csv)
    if unpaired_csv:
        io.write_csv(res.unpaired, unpaired_csv)
    if tied_csv:
        io.write_csv(res.tied, tied_csv)
    if modes_npz:
        res.modes.write(modes_npz)


@dataclass(frozen=True, eq=False)
class Verified:
    """What rule ``verify`` finds for one state (:func:`verify`): the tables' rows (``verify.csv``), the
    unpaired visible model modes (``unpaired_visible.csv``), the tied pairings' FE partners
    (``tied_pairings.csv``), the full solve's certificate (``certificate.json``) and its modes as the mesh
    check needs them (``optimum_modes.npz``)."""

    table: "pd.DataFrame"
    unpaired: "pd.DataFrame"
    tied: "pd.DataFrame"
    certificate: dict
    modes: "OptimumModes"


def verify(spec: ModelSpec, state: str, par: "IdentificationRecord", doc: dict, model,
           edge_matrices: list[str] | None = None) -> Verified:
    """Full FE re-solve of ``model`` at the identified parameters ``par`` (``params.json``; ``doc``: the surface
    model it was identified on): the tables' simulated frequencies (``spec``: the model's
    :class:`~jointid.config.typed.ModelSpec`).

    ``unpaired``: the model modes the test would clearly have seen that no measured mode is paired
    with (:mod:`jointid.identification.visibility`; columns ``model_mode, freq_Hz,
    target_Hz, misfit_pct, visibility_rel, description``), the misfits of the tables.
    ``tied``: the FE partners of the measured modes in every pairing that fits exactly as well as
    the chosen one (:func:`tied_pairings`).  ``certificate``: the full solve's (:func:`certificate`).

    With ``mesh.extrapolate_edges`` the simulated frequencies are the mesh-extrapolated ones at these
    parameters (:mod:`jointid.fe.extrapolate`): the base mesh's, scaled by the factors the
    identification recorded (``params.json``, ``edge_extrapolation.correction``, carried to these
    parameters to first order; its last pass bounds their drift), or, for a record without them,
    solved afresh on ``edge_matrices``.  ``simulation_mesh_Hz`` keeps the base mesh's; the surfaces are compared with the base mesh.
    """
    import pandas as pd

    from jointid.identification.optimum_modes import optimum_modes
    from jointid.identification.polish import solve_point

    freqs, shapes, desc, modes = solve_point(spec, model, par.theta, certify=True)
    cert = certificate(state, par, modes)
    at = optimum_modes(spec, model, par.names, [par.theta[n] for n in par.names], freqs, shapes, modes.phi,
                       modes.omega2)
    f_meas = np.asarray(par.f_meas_Hz)
    correction = par.correction_record
    lim = _extrapolated(spec, state, par, model, freqs, shapes, edge_matrices)
    f_all = freqs if lim is None else lim.limit_Hz
    from jointid.geometry.points import dof_labels
    from jointid.identification.visibility import misfit_table

    rule = visibility_rule(par, dof_labels(pd.DataFrame(model.meta["points"])))
    index, macs = _pairing(spec.solver.min_freq_Hz, par, doc, f_all, shapes, rule)
    paired = np.clip(index, 0, None)
    fe = np.where(index >= 0, freqs[paired], np.nan)
    sim, extra = fe, {}
    if lim is not None:
        sim = np.where(index >= 0, lim.limit_Hz[paired], np.nan)
        extra = {"simulation_mesh_Hz": fe, "edge_factor": np.where(index >= 0, lim.factor[paired], np.nan),
                 "edge_ratio": np.where(index >= 0, lim.ratio[paired], np.nan),
                 "edge_status": [lim.status[i] if i >= 0 else "" for i in index]}
    rows = pd.DataFrame({
        "order": np.arange(1, len(f_meas) + 1), "experimental_Hz": f_meas, "simulation_Hz": sim,
        "relative_error_pct": 100 * (sim - f_meas) / f_meas, **extra,
        "surface_Hz": list(par.f_surface_Hz), "surface_vs_fe_pct": 100 * (np.asarray(par.f_surface_Hz) - fe) / fe,
        "fe_mode": index + 1, "mac_to_tracked": macs,
        "description": [desc["description"][i] if i >= 0 else "unpaired" for i in index],
        "strain_joints": [float(desc["strain_joints"][i]) if i >= 0 else np.nan for i in index]})
    cols = ["model_mode", "freq_Hz", "target_Hz", "misfit_pct", "visibility_rel", "description"]
    seen = ([] if rule is None else
            misfit_table(rule, index, f_all, rule.visibility(shapes, f_all), f_meas, list(desc["description"])))
    for m in seen:
        log(f"verify[{state}]: unpaired but clearly visible: {m['freq_Hz']:.0f} Hz {m['description']} "
            f"({m['misfit_pct']:+.1f} % from {m['target_Hz']:.0f} Hz, the nearest measured mode or band edge)")
    tied = tied_pairings(par, doc, shapes)
    for a, grp in tied.groupby("alternative"):
        moved = [f"measured mode {o} with FE mode {m if m > 0 else 'none'}" for o, m, c in
                 zip(grp["order"], grp["fe_mode"], index + 1) if m != c]
        log(f"verify[{state}]: an exactly tied pairing pairs " + ", ".join(moved)
            + f" (the choice between them: {par.tie_rule.rule if par.tie_rule else 'not recorded'})")
    log(f"verify[{state}]: FE max |error| {np.nanmax(np.abs(rows.relative_error_pct)):.2f} %, "
        f"surface vs FE (base mesh) max {np.nanmax(np.abs(rows.surface_vs_fe_pct)):.2f} %")
    if lim is not None and par.fe_polish is not None:
        # with the recorded factors: the full solve against the polish's reduced solver; re-solved: fresh factors
        drift = 100 * (sim / np.asarray(par.fe_polish.f_fe_Hz) - 1)
        why = ("the same factors: full solve vs the polish's reduced basis" if correction else
               "its factors come from its previous optimum, to first order")
        log(f"verify[{state}]: extrapolated frequencies vs the identification's: max "
            f"{np.nanmax(np.abs(drift)):.2e} % ({why})")
    return Verified(rows, pd.DataFrame(seen, columns=cols), tied, cert, at)
