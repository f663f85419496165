"""Rules ``scout`` and ``identify``: one state's joint parameters from its measured modes.

The multistart on the response surfaces (:func:`jointid.identification.updating.identify_state`),
the pairing of frequency-only states shared by all states
(:func:`jointid.identification.updating.identify_states_jointly`) and the FE polish
(:mod:`jointid.identification.polish`); rule ``scout`` is the same stage without the model matrices
(surfaces only, the first optimum of the zoomed DOE).

Imports of the numerical modules are inside the functions (see :mod:`jointid.stages.model`).
"""

from __future__ import annotations

import numpy as np

from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.options import IdentifyOptions
    from jointid.config.typed import ModelSpec

AMBIGUOUS_DCHI2 = 4.0  # pairings closer than this in summed chi-square are reported as alternatives


def measured_modes(opts: IdentifyOptions, state: str, pts):
    """``(frequencies, shapes or None, frequency uncertainty in %)`` of one state's measured modes
    (``pts``: the measuring-point table).  With per-mode uncertainties in modes.csv
    (``freq_uncertainty_pct``, e.g. from the EMA) the uncertainty is their root mean square, and
    :func:`noise_weights` weights each mode by its own."""
    from jointid.correlate.pairing import below_band
    from jointid.data.dataset import read_dataset
    from jointid.errors import DataError
    from jointid.geometry.points import dof_labels

    ds = read_dataset(opts.datasets[state], measuring_points=pts)
    low = below_band(ds.name, {state: ds.freqs(state)}, opts.min_freq_Hz)
    if low:
        raise DataError(low)
    shapes = None
    if ds.shapes is not None and state in set(ds.shapes["state"]):
        shapes = ds.shape_matrix(state, dof_labels(pts))
    sigma_pct = ds.conditions.get("frequency_uncertainty_pct", opts.frequency_uncertainty_pct)
    per = ds.frequency_sigma_rel(state)
    if per is not None:
        sigma_pct = 100 * float(np.sqrt(np.mean(per ** 2)))
    return ds.freqs(state), shapes, float(sigma_pct)


def noise_weights(opts: IdentifyOptions, state: str, pts, sigma_pct: float, weights):
    """``identify.weights`` (None: ones) times each mode's ``(sigma / sigma_i)^2`` where modes.csv gives
    per-mode frequency uncertainties ``sigma_i`` (``sigma``: :func:`measured_modes`' root mean square):
    the fit's residual of mode i is then in units of its own uncertainty.  ``weights`` as given
    without per-mode uncertainties."""
    from jointid.data.dataset import read_dataset

    per = read_dataset(opts.datasets[state], measuring_points=pts).frequency_sigma_rel(state)
    if per is None:
        return weights
    w = np.ones(len(per)) if weights is None else np.asarray(weights, float)
    return w * (sigma_pct / 100 / per) ** 2


def visibility_rule(opts: IdentifyOptions, state: str, pts):
    """The observability rule of ``state`` (:class:`jointid.identification.visibility.VisibilityRule`),
    from its dataset's ``test_setup`` (default: the hammer at ``harmonic.drive_point`` in x, y and z,
    the responses where shapes were measured, else at every point in x, y and z); None when
    ``identify.visible_threshold`` is null."""
    from jointid.data.dataset import read_dataset
    from jointid.geometry.points import dof_labels
    from jointid.identification.visibility import dataset_rule

    if opts.test_setup.visible_threshold is None:
        return None
    folder = opts.datasets[state]
    ds = read_dataset(folder, measuring_points=pts)
    labels = dof_labels(pts)
    shapes = None
    if ds.shapes is not None and state in set(ds.shapes["state"]):
        shapes = ds.shape_matrix(state, labels)
    return dataset_rule(ds, state, labels, list(pts["point"]), shapes, opts.test_setup,
                        f"{folder}/conditions.yaml")


def tie_damping(opts: IdentifyOptions, state: str, f_meas) -> tuple:
    """``(damping ratio of each measured mode or None, its source)`` for the resolvability rule among
    tied pairings (:func:`jointid.identification.ties.tie_damping`): the dataset's measured ratios,
    else the configured ``harmonic.damping``."""
    from jointid.data.dataset import read_dataset
    from jointid.identification.ties import tie_damping as _tie_damping

    ds = read_dataset(opts.datasets[state])
    measured = ds.damping(state) if state in ds.states else None
    return _tie_damping(len(f_meas), measured, opts.damping, f_meas)


def pairing_notes(doc: dict, state: str, states: list[str], shared, info: dict, rule: str) -> list[str]:
    """Warnings on the pairing of frequency-only states: competing pairings of about equal fit, and
    the pairing the other rule (``identify.pairing``) would choose."""
    tm = lambda p: [doc["tracked_modes"][j] for j in p]  # noqa: E731
    own = info[state]["own"]
    k = len(doc["names"])
    if rule == "shared":
        chi2 = {tuple(c["pairing"]): c["chi2"] for c in info["candidates"]}
        dof = max(1, sum(len(own) - k for _ in states))
        chosen, what = tuple(shared), "over all states"
    else:
        chi2 = {tuple(c["pairing"]): c["chi2_by_state"][state] for c in info["candidates"]}
        dof = max(1, len(own) - k)
        chosen, what = tuple(own), "in this state"
    best = chi2[chosen]
    # chi2 scaled by its value per degree of freedom when the best fit is itself poor (then a model
    # error, not the noise, sets the scatter)
    scale = max(1.0, best / dof)
    close = sorted((v, p) for p, v in chi2.items() if p != chosen and (v - best) / scale < AMBIGUOUS_DCHI2)
    notes = []
    if close:
        notes.append(f"ambiguous pairing: besides tracked modes {tm(chosen)} (chi2 {best:.1f} {what}, {dof} "
                     "degrees of freedom) also " + "; ".join(f"tracked modes {tm(p)} (chi2 {v:.1f})" for v, p in close)
                     + f" fit within delta chi2 < {AMBIGUOUS_DCHI2:g}" + (f" (scaled by chi2/dof = {scale:.1f})"
                                                                          if scale > 1 else "")
                     + ": frequencies alone cannot tell them apart; measured shapes would")
    if list(shared) != own:
        if rule == "shared":
            notes.append(f"on its own this state would pair its measured modes with tracked modes {tm(own)} "
                         f"instead of {tm(shared)}: one pairing for all states ({', '.join(states)}) fits them "
                         "best together (identify.pairing: shared)")
        else:
            diff = [i + 1 for i, (a, b) in enumerate(zip(own, shared)) if a != b]
            notes.append(f"measured mode(s) {', '.join(map(str, diff))} pair with other tracked modes here "
                         f"({tm(own)}) than one pairing shared by all states would ({tm(shared)}): either the "
                         "modes swap order between the states or a pairing is off (identify.pairing: shared "
                         "forces one)")
    return notes


def _shared_pairing(opts, doc, state, states, pts, lower, upper, weights, rule):
    # many parameters: the inputs of the joint pairing that identify has read (surfaces, states, bounds, weights, rule)
    """``(shared pairing, joint-pairing record, notes)`` of frequency-only states of equal mode counts
    (:func:`jointid.identification.updating.identify_states_jointly`); ``(None, None, [])`` otherwise."""
    from jointid.identification.updating import identify_states_jointly

    others = {s: measured_modes(opts, s, pts) for s in states}
    if not (all(o[1] is None for o in others.values()) and len({len(o[0]) for o in others.values()}) == 1):
        return None, None, []
    damping = {s: tie_damping(opts, s, o[0]) for s, o in others.items()}
    shared, joint_info = identify_states_jointly(
        doc, {s: o[0] for s, o in others.items()}, lower, upper, weights=weights,
        n_starts=opts.n_starts, seed=opts.seed, sigma_rel={s: o[2] / 100 for s, o in others.items()},
        rule={s: visibility_rule(opts, s, pts) for s in states},
        damping=None if any(d[0] is None for d in damping.values()) else {s: d[0] for s, d in damping.items()})
    joint_info["tie_rule"]["damping_ratio_source"] = {s: d[1] for s, d in damping.items()}
    return shared, joint_info, pairing_notes(doc, state, states, shared, joint_info, rule)


def _count_note(n_meas: int, n_par: int) -> str:
    return (f"{n_meas} measured frequencies for {n_par} identified parameters: "
            + ("underdetermined, the values are one of many that fit equally well"
               if n_meas < n_par else "no residual degree of freedom is left")
            + " and the intervals mean little — measure more modes, or fix parameters (joints.fixed)")


def _polish_notes(polish: dict, shapes) -> list[str]:
    """Warnings of the FE polish: parameters on a bound, model modes in the band without a partner."""
    msgs = [f"{n} sits on a bound of joints.parameters.{n} after the FE polish — widen the bounds"
            for n in polish["on_bound"]]
    seen = polish.get("unpaired_visible") or []
    if seen:
        msgs.append(f"{len(seen)} model mode(s) the test would clearly have seen have no measured partner and "
                    "count as misfits: " + "; ".join(
                        f"{m['freq_Hz']:.0f} Hz ({m['misfit_pct']:+.1f} % from {m['target_Hz']:.0f} Hz, the nearest measured mode or band edge, "
                        f"visibility {m['visibility_rel']:.2f} of the weakest paired mode)" for m in seen))
    skipped = polish["unpaired_in_band_Hz"]
    if skipped:
        msgs.append(f"{len(skipped)} model mode(s) inside the measured band ("
                    + ", ".join(f"{f:.0f}" for f in skipped) + " Hz) have no measured partner: "
                    + ("the frequency-only pairing skipped them. Either the test missed them (check that "
                       "the excitation and measuring points could see them) or the reconstruction is off; "
                       "measured shapes would make the pairing unambiguous (MAC)" if shapes is None else
                       "the measured shapes pair with other model modes; check whether the test could "
                       "have missed them"))
    return msgs


def _zoom_notes(names, theta, lower, upper, polish, res) -> list[str]:
    """Warnings of an identification on the zoomed DOE's surfaces: the optimum outside or on its box."""
    out_of_box = [f"{n} = {t:.3g} (box {a:.3g}..{b:.3g})" for n, t, a, b in zip(names, theta, lower, upper)
                  if not a * (1 - 1e-9) <= t <= b * (1 + 1e-9)]
    if out_of_box:
        return ["the optimum lies outside the zoomed DOE box, where its surfaces extrapolate: "
                + "; ".join(out_of_box) + " — raise doe.zoom.half_width_decades"]
    if polish is None and res.on_bound:
        return [f"{', '.join(res.on_bound)} on an edge of the zoomed DOE box: the optimum may lie beyond "
                "it — raise doe.zoom.half_width_decades or enable identify.fe_polish"]
    return []


def _face_of(spec: ModelSpec, name: str) -> str:
    from jointid.fe.model import joint_terms

    terms = joint_terms(spec.joints, spec.mesh_file)[name]
    return "+".join(sorted({t[2:].rsplit("_", 1)[0] for t in terms}))  # K_<face>_<component>


def _per_carriage(spec: ModelSpec, names, theta, ci_lo, ci_hi, areas: dict) -> dict:
    """The parameters as springs of one carriage (N/um): value x its faces' contact area per carriage."""
    from jointid.identification.record import Interval

    per_carriage = {}
    for n, th, lo, hi in zip(names, theta, ci_lo, ci_hi):
        a = areas.get(_face_of(spec, n), 0.0)
        per_carriage[n.replace("_N_per_m3", "_per_carriage_N_per_um")] = Interval(th * a * 1e-6, lo * a * 1e-6,
                                                                                  hi * a * 1e-6)
    return per_carriage


def _polish_step(spec: ModelSpec, state: str, names: list[str], fit, surface_theta, matrices, rom, edges: bool):
    """The FE polish of the surface optimum ``surface_theta`` (N/m^3; with ``edges`` its repeats on
    frequencies extrapolated over the mesh with one and two more edge levels, each built in this job
    when its turn comes); ``fit``: a :class:`jointid.identification.polish.PolishFit`.

    The 95 % intervals: :func:`jointid.identification.polish.polish_intervals`.
    Returns ``(theta, ci95_low, ci95_high, frequencies fitted, polish, edge record)``.
    """
    from jointid.fe.model import edge_level_builders
    from jointid.identification.polish import extrapolated_polish, polish_intervals, polish_optimum

    surface_theta = np.asarray(surface_theta, float)
    polish = polish_optimum(spec, names, matrices, surface_theta, fit, rom=rom)
    edge = None
    if edges:
        builders = edge_level_builders(spec, progress=lambda m: log(f"identify[{state}]: {m}"))
        edge, polish = extrapolated_polish(spec, state, names, matrices, builders, polish, fit, rom=rom)
    if polish.get("certificate"):
        log(f"identify[{state}]: optimum's {polish['certificate'].describe()}")
    theta = polish["theta"]
    polish["interval_scale"], ci_lo, ci_hi = polish_intervals(polish)
    return theta, ci_lo, ci_hi, polish["f_fe"], polish, edge


def _polish_fit(opts: IdentifyOptions, state: str, doc: dict, pairing, measured: tuple, weights, fixed, rule):
    # many parameters: the state, its surface and pairing, the measured modes with their weights and the test
    """What the FE polish fits (:class:`jointid.identification.polish.PolishFit`): the measured modes
    ``measured`` (:func:`measured_modes`), following the surface model's reference shapes of their paired
    modes, in the configured bounds; their measured shapes, where there are any, as a block of rows of
    their own (at the dataset's stated shape uncertainty, else estimated).  Frequency-only data paired
    each state by itself (``fixed`` None) are re-paired at every iterate."""
    from jointid.identification.polish import PolishFit

    f_meas, shapes, sigma_pct = measured
    shape_pct = None if shapes is None else stated_shape_uncertainty(opts.datasets[state])
    b_lo, b_hi = opts.model.joints.lower_N_per_m3, opts.model.joints.upper_N_per_m3
    return PolishFit(f_meas, np.asarray(doc["ref_shapes"])[:, pairing], b_lo, b_hi, weights=weights,
                     sigma_rel=sigma_pct / 100, repair=shapes is None and fixed is None, rule=rule, shapes=shapes,
                     shape_sigma_rel=None if shape_pct is None else float(shape_pct) / 100)


def stated_shape_uncertainty(folder: str) -> float | None:
    """The ``shape_uncertainty_pct`` of the dataset in ``folder`` (conditions.yaml; None: not stated, the polish
    estimates it)."""
    from jointid.data.dataset import read_dataset

    value = read_dataset(folder).conditions.get("shape_uncertainty_pct")
    return None if value is None else float(value)


def _paired_by(shapes, fixed):
    """How the measured modes were paired (:class:`jointid.correlate.pairing.PairedBy`): by MAC with measured
    ``shapes``, else by frequency, shared by all states when the pairing is ``fixed``."""
    from jointid.correlate.pairing import PairedBy

    if shapes is not None:
        return PairedBy.MAC
    return PairedBy.FREQUENCY_SHARED if fixed is not None else PairedBy.FREQUENCY


def intervals(names, theta, ci_lo, ci_hi) -> dict:
    """``{name: Interval}`` of values and their 95 % intervals."""
    from jointid.identification.record import Interval

    return {n: Interval(th, lo, hi) for n, th, lo, hi in zip(names, theta, ci_lo, ci_hi)}


def _identification(state, doc, res, pairing, paired_by, joint_info, f_meas, sigma_pct, solution, polish, edge, rom,
                    per_carriage, msgs):
    # many parameters: one per part of the record that identify computed (the surface fit, the pairing, the polish)
    """The :class:`jointid.identification.record.IdentificationRecord` of the fit, without the parts that
    :func:`identify` adds (tie rule, observability, joint damping).  ``solution``: ``(theta, ci95_low,
    ci95_high, frequencies fitted)``."""
    from jointid.identification.record import FePolish, IdentificationRecord, PolishedOn, SurfaceStage, floats

    names, lower, upper = doc["names"], doc["lower"], doc["upper"]
    theta, ci_lo, ci_hi, f_final = solution
    return IdentificationRecord(
        parameters=intervals(names, theta, ci_lo, ci_hi), state=state,
        surface_optimum={n: float(t) for n, t in zip(names, np.asarray(res.theta, float))},
        surface_stage=SurfaceStage(doc.get("stage", "global")),
        surface_box={n: (float(a), float(b)) for n, a, b in zip(names, lower, upper)},
        fe_polish=None if polish is None else FePolish.of(polish, PolishedOn.ROM if rom else PolishedOn.FE),
        edge_extrapolation=edge, per_carriage=per_carriage, x_coded=floats(res.x_coded),
        pairing_tracked_mode=tuple(doc["tracked_modes"][j] for j in pairing),
        pairing_columns=tuple(np.asarray(pairing).tolist()), paired_by=paired_by, joint_pairing=joint_info,
        f_meas_Hz=floats(f_meas), f_surface_Hz=floats(res.f_model),
        residual_pct=floats(100 * (np.asarray(f_final) - f_meas) / f_meas),
        cost=res.cost, condition_number=res.condition_number, weak_combination=res.weak_combination,
        on_bound=tuple(res.on_bound if polish is None else polish["on_bound"]),
        n_starts_agreeing=res.n_starts_agreeing, warnings=tuple(msgs), frequency_uncertainty_pct=sigma_pct,
        model_error=None if polish is None else _model_error(polish, sigma_pct, state))


def _model_error(polish: dict, sigma_pct: float, state: str) -> dict:
    """The polish's model error record: the frequency block's, and the shape block's where shapes are fitted
    (in units of their stated noise)."""
    from dataclasses import replace

    from jointid.identification.model_error import from_chi2

    me = from_chi2(polish["chi2"], polish["dof"], sigma_pct / 100, reference=f"identify[{state}]")
    if polish.get("shape_dof"):
        me = replace(me, shape=from_chi2(polish["shape_chi2"], polish["shape_dof"], polish["shape_uncertainty"],
                                         reference=f"identify[{state}]"))
    return me.record()


def run_identify(opts: IdentifyOptions, state: str, surface_json: str, points_csv: str, out_json: str,
                 matrices: str | None = None, rom: str | None = None, states: list[str] | None = None,
                 summary_json: str | None = None) -> None:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rules ``identify`` and ``scout``: :func:`identify` on the rule's files -> ``out_json`` (``params.json``).
    ``summary_json``: the model summary of rule ``mesh`` (default: ``summary.json`` beside ``points_csv``), for
    the per-carriage values."""
    summary = summary_json or points_csv.replace("measuring_points.csv", "summary.json")
    rec = identify(opts, state, io.read_json(surface_json), io.read_csv(points_csv),
                   io.read_json(summary)["contact_area_per_carriage_m2"], matrices, rom=rom, states=states)
    rec.write(out_json)


def identify(opts: IdentifyOptions, state: str, doc: dict, pts, areas: dict, matrices=None, rom: str | None = None,
             states: list[str] | None = None):
    # many parameters: the stage's inputs (surfaces, points, areas, model) and its variants (ROM, states)
    """Identify one state's joint parameters: multistart on the surfaces, then the polish.

    ``doc``: the surface model (rule ``fit_surface``); ``pts``: the measuring points; ``areas``: the contact
    area per carriage of each joint face (m^2, the model summary's ``contact_area_per_carriage_m2``), for the
    per-carriage values.  The polish (``identify.fe_polish``) runs on the full FE model (``matrices``: the
    model file, or the :class:`jointid.fe.fem.Model` itself; none: rule ``scout``, the surfaces alone), or on
    the verified reduced-order model ``rom`` when one is given (``solver.method: rom``; the verify stage then
    checks the result with a full solve).  With ``states`` (all states of the run) and frequencies alone in
    every one, in equal numbers, ``identify.pairing: shared`` (the default) pairs the measured modes with the
    same tracked modes in every state (:func:`jointid.identification.updating.identify_states_jointly`);
    ``independent`` pairs each state by its own frequencies, re-paired at every polish iterate; the notes name
    competing pairings.  With ``mesh.extrapolate_edges`` the polish is repeated on mesh-extrapolated frequencies
    (:func:`jointid.identification.polish.extrapolated_polish`).  Each call starts a new polish session
    (:func:`jointid.identification.polish.forget_session`), as a new process would.  Returns the
    :class:`jointid.identification.record.IdentificationRecord` (``params.json``).
    """
    from dataclasses import replace

    from jointid.identification import joint_damping, updating  # scipy.optimize: not when the Snakefile imports us
    from jointid.identification.polish import forget_session
    from jointid.identification.record import Observability, TieRule

    forget_session()
    f_meas, shapes, sigma_pct = measured_modes(opts, state, pts)
    weights = noise_weights(opts, state, pts, sigma_pct, None if opts.weights is None else np.asarray(opts.weights, float))
    lower, upper = np.array(doc["lower"]), np.array(doc["upper"])
    names, zoom = doc["names"], doc.get("stage") == "zoom"
    rule = opts.pairing  # the schema gives the default
    shared, joint_info, pair_msgs = None, None, []
    log(f"identify[{state}]: {len(f_meas)} measured modes, {len(doc['tracked_modes'])} tracked modes; pairing "
        f"them on the {'zoomed ' if zoom else ''}response surfaces")
    if states and len(states) > 1 and state in states and shapes is None:
        shared, joint_info, pair_msgs = _shared_pairing(opts, doc, state, states, pts, lower, upper, weights, rule)
    fixed = shared if rule == "shared" else None
    vis_rule = visibility_rule(opts, state, pts)
    zeta, zeta_source = tie_damping(opts, state, f_meas)
    decision = {}
    res, pairing, msgs = updating.identify_state(doc, f_meas, lower, upper, meas_shapes=shapes, weights=weights,
                                        n_starts=opts.n_starts, seed=opts.seed, sigma_rel=sigma_pct / 100,
                                        pairing=fixed, rule=vis_rule, damping=zeta, decision=decision)
    tie_rule = joint_info["tie_rule"] if fixed is not None else (
        {**decision, "damping_ratio_source": {state: zeta_source}} if decision else None)
    msgs += pair_msgs
    if len(f_meas) <= len(names):
        msgs.insert(0, _count_note(len(f_meas), len(names)))
    if zoom:  # an edge of the zoomed box is no bound of the parameters: the FE polish may pass it
        msgs = [m for m in msgs if not any(m.startswith(f"{n} sits on its") for n in names)]
    theta, ci_lo, ci_hi = np.asarray(res.theta, float), res.ci_lower, res.ci_upper
    f_final, polish, edge, edges = res.f_model, None, None, opts.extrapolate_edges
    if edges and not (matrices is not None and opts.fe_polish):
        msgs.append("mesh.extrapolate_edges needs identify.fe_polish: the frequencies fitted are those of the "
                    "base mesh")
    if matrices is not None and opts.fe_polish:
        fit = _polish_fit(opts, state, doc, pairing, (f_meas, shapes, sigma_pct), weights, fixed, vis_rule)
        theta, ci_lo, ci_hi, f_final, polish, edge = _polish_step(
            opts.model, state, doc["names"], fit, res.theta, matrices, rom, edges)
        msgs += _polish_notes(polish, shapes)
    if zoom:
        msgs += _zoom_notes(names, theta, lower, upper, polish, res)
    per_carriage = _per_carriage(opts.model, names, theta, ci_lo, ci_hi, areas)
    damping = joint_damping.params_entry(opts.datasets[state], state, names, polish, f_meas, weights, edge, log)
    rec = replace(_identification(state, doc, res, pairing, _paired_by(shapes, fixed), joint_info, f_meas, sigma_pct,
                                  (theta, ci_lo, ci_hi, f_final), polish, edge, rom, per_carriage, msgs),
                  tie_rule=None if tie_rule is None else TieRule.from_json(tie_rule),  # None: no frequency-only choice
                  observability=None if vis_rule is None else Observability.of(vis_rule),
                  joint_damping=damping.get("joint_damping"))
    log(f"identify[{state}]: " + ", ".join(f"{n} = {t:.4g}" for n, t in zip(names, theta))
        + f"; max |error| {np.abs(rec.residual_pct).max():.2f} %")
    if tie_rule and len(tie_rule["tied"]) > 1:
        log(f"identify[{state}]: {len(tie_rule['tied'])} exactly tied pairings, chosen by {tie_rule['rule']}: "
            + "; ".join(f"tracked modes {[doc['tracked_modes'][j] for j in t['pairing']]} "
                        f"{ {True: 'resolvable', False: 'not resolvable'}.get(t['resolvable'], 'resolvability not judged')} (damping ratio needed "
                        f"{t['damping_ratio_needed']:.4f})" for t in tie_rule["tied"]))
    for m in msgs:
        log("warning: " + m)
    return rec
