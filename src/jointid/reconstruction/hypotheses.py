"""Reconstruction hypotheses: the rig's uncertain choices compared on the measured data.

The rig is a reconstruction from a paper, so several of its choices are guesses: how the base is
supported, what the first measured mode is, the table's material and thickness, the motor mass, the
rail spacing, the joint law.  Each *hypothesis* (``hypotheses:`` in config.yaml) is one set of such
choices, written as config overrides plus optional library effects (``jointid.diagnosis.effects``)
and fixed joint parameters.  Every hypothesis is fitted to the same data by the same machinery as the
diagnosis (:class:`jointid.diagnosis.fitting.Diagnoser`: reduced full-FE solves, one pairing for all
states, the observability rule's misfits counted) under the linked two-state law, and the
hypotheses are ranked by QAICc, AICc at the stated noise plus the model error of the best of them
(:mod:`jointid.identification.model_error`; docs/reconstruction.md, "Hypotheses").

The linked two-state law
------------------------
One joint law for both states: the joint stiffness per area of carriage c in the contact
directions (``linked.directions``, default X and Y) is

    k = k0 * ((P + F_c) / (P + F_c,0)) ** beta

with F_c the carriage's load from the statics load share of the motor attraction plus the carried
weight, F_c,0 the weight-only load (power off: k = k0) and P the block preload.  This is the library
effect ``em_preload``; beta is fitted in 0..1 and P is chosen among the catalogue preload classes
``linked.preload_classes_N`` (the best class is reported; P and beta are nearly collinear with two
force levels, so the profile over the classes is reported too).  The feed direction (Z) is not a
contact direction of a guide: ``k_feed`` is one constant for both states, the servo or brake term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointid.config.hypotheses import COEFFICIENT_KEYS, HYPOTHESIS_KEYS, MODEL_SECTIONS, LinkedLaw  # noqa: F401
from jointid.config.typed_diagnosis import DiagnosisSettings

from jointid.diagnosis.effects import EFFECTS, check_hypothesis_effects, enabled_effects, pressure_ratio  # noqa: F401
from jointid.diagnosis.fitting import Diagnoser, Fit, print_log
from jointid.reconstruction.predictions import measurement_predictions
from jointid.diagnosis.results import block_error, frequency_rows, log_interval
from jointid.diagnosis.criteria import aicc
from jointid.diagnosis.variants import EffectSpec, StateData, Variant
from jointid.progress import Steps

__all__ = ["HYPOTHESIS_KEYS", "MODEL_SECTIONS", "COEFFICIENT_KEYS", "LinkedLaw", "check_hypothesis_effects",
           "linked_variant", "fit_hypothesis", "fit_with", "record", "search", "Searched", "state_joints", "CERTIFIED", "NOT_CERTIFIED",
           "not_certified", "search_tol", "chi2_bound"]


def _effect_specs(effects: dict) -> list[EffectSpec]:
    """The hypothesis's effects (``effects`` of its config, the linked law's own effect left out)."""
    specs = []
    for en in enabled_effects(effects):
        if en.effect.name != "em_preload":  # the linked law is this effect
            specs.append(EffectSpec(en.effect, dict(en.values), dict(en.options),
                                    [p.name for p in en.effect.params] if en.fit else []))
    return specs


def linked_variant(system, settings: DiagnosisSettings, law: LinkedLaw | None, preload_N: float = 0.0) -> Variant:
    """The variant of a hypothesis (``settings``: of its configuration): its effects, plus the contact law at
    ``preload_N`` unless ``law`` is None (one force level: the law cannot act)."""
    specs = _effect_specs(settings.effects)
    if law is not None:
        em = EFFECTS["em_preload"]
        opts = {**em.options, "preload_N": float(preload_N), "directions": list(law.directions)}
        specs.append(EffectSpec(em, {"beta": law.beta_start}, opts, ["beta"]))
    return Variant(system, settings, specs, theta_fixed=dict(settings.model.joints.fixed_N_per_m3))


def _forces_differ(data: list[StateData]) -> bool:
    return len({round(d.info.em_force_N, 6) for d in data}) > 1


def fit_hypothesis(system, settings: DiagnosisSettings, law: LinkedLaw, data: list[StateData], *, start_basis=None,
                   certify: bool = True, log=print_log) -> dict:
    """Fit one hypothesis (``settings`` and ``law``: of its configuration,
    :func:`jointid.config.hypotheses.hypothesis_config`) to ``data`` under the linked law; the best preload
    class by chi-square.

    Returns a JSON-ready record: chi-square, counts, AICc, parameters with 95 % intervals scaled by
    ``max(1, sqrt(chi2 / dof))``, per-state errors (misfits counted), the unpaired visible modes, the
    pairing, the profile over the preload classes and ``predictions``, what the fitted model predicts
    for measurements not made yet (:func:`jointid.reconstruction.predictions.measurement_predictions`).  ``start_basis``: a basis of ``system`` to start
    the reduced solver from (:mod:`jointid.stages.basis`).
    """
    # measured shapes are fitted as in the diagnosis: a block of their own, with its own model error in the ranking
    return fit_with(Diagnoser(system, settings, data, start_basis=start_basis, tol=search_tol(data), log=log), law,
                    log, certify=certify)


def fit_with(diag: Diagnoser, law: LinkedLaw, log=print_log, *, certify: bool = True) -> dict:
    """:func:`fit_hypothesis` with a diagnoser of the hypothesis's system, settings and data (its reduced solver
    possibly shared with other hypotheses on the same terms, :func:`jointid.diagnosis.terms.build_systems`):
    :func:`search` and its :func:`record`, certified unless ``certify`` is false (the certificate is then
    left to the job that ranks it with the others: :data:`PENDING`)."""
    rec = record(diag, search(diag, law, log), certify=certify)
    if not certify:
        rec["certificate"] = PENDING
    return rec


@dataclass
class Searched:
    """A hypothesis's fit before its certificate: the best preload class's fit, that class (None with one force
    level), the profile over the classes and how many there were."""

    fit: Fit
    preload_N: float | None
    profile: list
    n_choices: int


def search(diag: Diagnoser, law: LinkedLaw, log=print_log) -> Searched:
    """The fit of a hypothesis under the linked law (``diag``: of its system, settings and data): the best
    preload class by chi-square, each class continued from the one before.  Every solve is checked in the
    full space (residuals); the Sturm count of the certificate is :func:`record`'s."""
    system, settings, data = diag.system, diag.settings, diag.data
    linked = _forces_differ(data)
    classes = law.preload_classes_N if linked else (law.preload_classes_N[0],)
    profile, best = [], None
    x_prev = None
    index = None
    steps = Steps(len(classes))
    for P in classes:  # continuation: each class starts at the optimum (and pairing) of the one before
        var = linked_variant(system, settings, law if linked else None, P)
        if x_prev is None:  # the configured start and the hypothesis's effects at their null, best kept
            fit = min(diag.fit_starts(var, _starts(var)), key=lambda f: f.chi2)
        else:
            fit = diag.fit(var, x_prev, index=index)
        x_prev, index = fit.x, fit.ev.index
        beta = fit.variant.physical(fit.x).get("em_preload.beta", float("nan"))
        profile.append({"preload_N": float(P), "beta": float(beta), "chi2": fit.chi2})
        log(f"hypotheses: preload {P:g} N {steps.done()}: chi2 {fit.chi2:.2f}, beta {beta:.3f}")
        if best is None or fit.chi2 < best[0].chi2 - 1e-9:
            best = (fit, P)
    fit, P = best
    return Searched(fit, P if linked else None, profile, len(classes))


SEARCH_TOL = 1e-4
"""The estimated relative eigenvalue error every solve of a hypothesis's search is refined to (full-space residual
check) when its data have frequencies only: a frequency error of at most 5e-5, 200 times below the stated noise
of 1 %.  A rejected hypothesis needs its fit, not a certificate; its chi-square is within :func:`chi2_bound` of
the exact model's, and a hypothesis that bound could bring into the admissible set is certified
(:func:`jointid.stages.hypotheses.run_hypotheses`).  Measured on the paper's data against a search at 1e-5 (one
process, profiled): the hypotheses on the run model 125 s and 146 s instead of 177 s; chi-square of the rejected
ones moved by at most 1.3e-4 (relative, within :func:`chi2_bound`) where the fit found the same optimum, the
certified ones by at most 7e-6; mode1_base_mode (chi-square 20 420, far outside the admissible set) ended in
another basin 0.22 % lower; the ranking and the admissible set unchanged."""
SHAPE_SEARCH_TOL = 1e-5
""":data:`SEARCH_TOL` when measured shapes are fitted.  A Ritz vector's error goes as the square root of its
eigenvalue's (about 1 % of a shape at 1e-4), which is of the order of a shape's noise; at 1e-5 the search moved
chi-square by at most 9e-6 against 1e-6 (docs/reconstruction.md)."""
CERTIFY_TOL = 1e-6
"""The tolerance of a certified answer (:func:`record` with ``certify``): the fit asked again from its optimum
with every solve refined to it, and the Sturm count."""
CERTIFIED = "residual check and Sturm count at the optimum"
"""A record's ``certificate`` when it was asked again from its optimum with the certificate."""
NOT_CERTIFIED = "none: not admissible in this run's ranking, so no answer rests on it"
"""How a record's ``certificate`` begins when it was not (:func:`not_certified`,
:func:`jointid.stages.hypotheses.run_hypotheses`)."""


def search_tol(data: list[StateData]) -> float:
    """The search's tolerance for ``data``: :data:`SHAPE_SEARCH_TOL` when a state has measured shapes, else
    :data:`SEARCH_TOL`."""
    return SHAPE_SEARCH_TOL if any(d.shapes is not None for d in data) else SEARCH_TOL


def not_certified(tol: float) -> str:
    """The ``certificate`` of a record left uncertified, its fit searched at ``tol``."""
    return (f"{NOT_CERTIFIED}; every solve of its fit was checked in the full space (residuals, to an estimated "
            f"relative eigenvalue error of {tol:.0e}; certified answers {CERTIFY_TOL:.0e}), without the Sturm count")


def chi2_bound(chi2: float, n_rows: int, tol: float, sigma_rel_min: float) -> float:
    """How far the frequency chi-square of a fit whose solves are refined to ``tol`` (relative eigenvalue error) can
    lie from the exact model's, to first order: each frequency is off by at most ``e = tol / 2`` (relative), so
    each standardised residual by ``e / sigma`` and ``|d chi2| <= 2 (e / sigma) sum |z| + n (e / sigma)^2``, with
    ``sum |z| <= sqrt(n chi2)``.  With the fit's pairing held, the same bound holds between the optimum of its basin
    on the reduced model and on the exact one (a minimum moves by at most the largest change of the function).
    Another path can end in another basin or pairing, with any tolerance or round-off; this bound says nothing
    about that (on the paper's data mode1_base_mode's chi-square of 20 420 moved by -0.22 % between searches at
    1e-5 and 1e-4, where its bound is 4.9).  ``sigma_rel_min``: the smallest stated relative frequency
    uncertainty."""
    a = 0.5 * tol / max(sigma_rel_min, 1e-12)
    return float(2.0 * a * math.sqrt(max(n_rows, 0) * max(chi2, 0.0)) + n_rows * a * a)


PENDING = ("pending: fitted in a job of its own (its own model); the job of the hypotheses on the run's model ranks "
           "it with them and certifies it only if it is admissible")
"""The ``certificate`` of a record fitted apart whose certificate is left to the ranking with the others
(:func:`jointid.stages.hypotheses.run_hypotheses`, which replaces it by :data:`CERTIFIED` or :data:`NOT_CERTIFIED`)."""


def record(diag: Diagnoser, found: Searched, *, certify: bool) -> dict:
    """The JSON-ready record of a searched hypothesis (:func:`fit_record`).  With ``certify`` the fit is first
    asked again from its optimum with the certificate (residual check and Sturm count against the full model,
    which may move it) and the record gets ``predictions`` for the next measurement (the ranking job);
    without, the record says why not (:func:`not_certified`: a hypothesis outside the admissible set needs its
    fit, not a certificate), has no predictions, and carries ``chi2_solver_bound`` (:func:`chi2_bound` at the
    search's tolerance), which the ranking job uses to decide whom to certify."""
    tol = search_tol(diag.data)
    if certify and diag.solver is not None:
        diag.solver.tighten(CERTIFY_TOL)  # the search's tolerance was looser (search_tol)
    fit = diag.certify(found.fit) if certify else found.fit
    rec = fit_record(fit, diag.data, found.preload_N, found.profile, n_choices=found.n_choices)
    rec["certified"], rec["certificate"] = certify, CERTIFIED if certify else not_certified(tol)
    if not certify:
        sigma = min((float(np.min(d.mode_sigma())) for d in diag.data if len(d.f_meas)), default=np.inf)  # none: no rows
        rec["search_tol"], rec["chi2_solver_bound"] = tol, chi2_bound(rec["chi2"], rec["n_data"], tol, sigma)
    if certify:
        rec["predictions"] = measurement_predictions(diag, fit, diag.data)
    return rec


def _starts(var: Variant) -> list[np.ndarray]:
    """Start vectors: the configured start, and (when the variant has effects beyond the contact
    law) the same with those effects at their null — a fit from a strong effect can lock onto a
    pairing of its own."""
    x0 = var.x_start()
    x1 = x0.copy()
    for k, (i, p) in enumerate(var.slots):
        if var.effects[i].effect.name != "em_preload":
            x1[var.p + k] = p.t_near_null(0.0)
    return [x0] if np.array_equal(x0, x1) else [x0, x1]


def fit_record(fit: Fit, data: list[StateData], preload_N: float | None, profile: list, *, n_choices: int) -> dict:
    """The JSON-ready record of a fitted hypothesis (see :func:`fit_hypothesis`)."""
    n_data = sum(len(d.f_meas) for d in data)
    extra = 1 if n_choices > 1 else 0  # the preload class chosen from the data counts
    k = fit.k + extra
    blocks = fit.block_chi2(extra)  # the frequency rows, and the shape rows where shapes are fitted
    chi2 = blocks[0][1]
    dof = max(n_data - k, 1)
    scale = max(1.0, math.sqrt(chi2 / dof))
    # one block: the covariance at the stated noise widened by the frequency rows' lack of fit; with shape
    # rows, each block at its own model error and the per-mode (cluster-robust) check (Fit.scaled_covariance)
    cov = fit.covariance() * scale ** 2 if len(blocks) == 1 else fit.scaled_covariance(extra)
    params = []
    for j, label in enumerate(fit.variant.labels):
        value = fit.variant.physical(fit.x)[label]
        sd = math.sqrt(max(cov[j, j], 0.0))
        if j < fit.variant.p:  # log-parametrised joint stiffness
            lo, hi = log_interval(value, sd)
        else:
            p = fit.variant.slots[j - fit.variant.p][1]
            a, b = p.from_t(fit.x[j] - 1.96 * sd), p.from_t(fit.x[j] + 1.96 * sd)
            lo, hi = min(a, b), max(a, b)
        at_bound = bool(np.isclose(fit.x[j], fit.variant.lower[j], atol=1e-6)
                        or np.isclose(fit.x[j], fit.variant.upper[j], atol=1e-6))
        params.append({"parameter": label, "value": float(value), "ci95_low": float(lo),
                       "ci95_high": float(hi), "at_bound": at_bound})
    for name, v in fit.variant.theta_fixed.items():
        params.append({"parameter": name, "value": float(v), "ci95_low": float(v), "ci95_high": float(v),
                       "at_bound": False, "fixed": True})
    errors = fit.errors_pct(data)
    states = []
    for si, (d, e, s, p, fm) in enumerate(zip(data, errors, fit.state_summary(data), fit.pairings, fit.ev.f_model)):
        states.append({**s, "em_force_N": d.info.em_force_N, "joints_N_per_m3": state_joints(fit, d),
                       "dynamic_stiffness": dynamic_stiffness(fit, si),
                       "f_meas_Hz": [float(v) for v in d.f_meas],
                       "f_model_Hz": [float(v) for v in fm],
                       "error_pct": [float(v) for v in e],
                       "model_mode": [int(i) + 1 if i >= 0 else 0 for i in p.model_index]})
    lowest = min((float(np.sqrt(max(float(np.min(s.lam_all)), 0.0))) / (2 * math.pi)
                  for s in fit.ev.solutions if len(s.lam_all)), default=float("nan"))
    return {"chi2": chi2, "n_data": n_data, "n_params": k, "aicc": aicc(chi2, n_data, k),
            "dof": dof, "interval_scale": scale, "preload_N": preload_N, "preload_profile": profile,
            "residuals": [float(v) for v in fit.ev.r[frequency_rows(fit.ev)]],
            "residual_sigma_rel": [float(v) for v in fit.row_sigma(data)],
            "shape_chi2": blocks[1][1] if len(blocks) > 1 else 0.0,
            "shape_dof": blocks[1][2] if len(blocks) > 1 else 0,
            "shape_design_effect": fit.shape_design_effect(),  # rows that move together count less (ranking)
            "shape_sigma_rel": _shape_noise(fit, data),  # the stated shape noise (per mode's RMS), for the sentence
            "lowest_freq_Hz": lowest,
            "parameters": params, "states": states, "unpaired_visible": fit.unpaired_visible(data),
            "variant": fit.variant.name}


def _shape_noise(fit: Fit, data: list[StateData]) -> float | None:
    """The shape rows' stated noise (relative to each mode's RMS; :func:`block_error`), or None without them."""
    shape = block_error(fit.ev, data, fit.k).shape
    return None if shape is None else float(shape.sigma_noise_rel)


def dynamic_stiffness(fit: Fit, si: int) -> dict:
    """Table 1 under a fitted hypothesis, state ``si``: the minimum over ``harmonic.band_Hz`` of the
    drive-point dynamic stiffness ``|F/X|`` (``harmonic.drive_point``, ``harmonic.direction``) by modal
    superposition of the solved modes at the constant modal ratio ``harmonic.damping.damping_ratio``
    (:func:`jointid.response.ranges.band_minimum`; no residual flexibility), and the lowest resonance
    of a paired mode.  ``{}`` when the drive point is not a measuring point of the model."""
    from jointid.response.ranges import band_minimum

    h = fit.variant.settings.response
    label = f"{h.drive_point}:{h.direction}"
    labels = list(fit.variant.system.labels)
    if label not in labels:
        return {}
    sol = fit.ev.solutions[si]
    zeta = h.damping_ratio
    idx = np.asarray(fit.ev.index[si])
    paired = np.zeros(len(sol.freqs_Hz), bool)
    paired[idx[idx >= 0]] = True
    out = band_minimum(h.band_Hz, sol.freqs_Hz, np.full(len(sol.freqs_Hz), zeta),
                       np.zeros(len(sol.freqs_Hz)), np.asarray(sol.shapes, float)[labels.index(label)],
                       paired=paired, n_freq=h.n_freq)
    return {"k_min_N_per_m": out["k_min_N_per_m"], "f_at_min_Hz": out["f_at_min_Hz"],
            "k_paired_N_per_m": out["k_paired_N_per_m"], "damping_ratio": zeta}


def state_joints(fit: Fit, d: StateData) -> dict:
    """The joint stiffness per area in state ``d`` (N/m^3): each joint parameter times the contact law's
    factor ``((P + F_c)/(P + F_c,0))^beta`` averaged over the carriages, for the law's directions."""
    theta, vals = fit.variant.unpack(fit.x)
    out = dict(theta)
    for spec, v in zip(fit.variant.effects, vals):
        if spec.effect.name != "em_preload" or v["beta"] == 0.0 or d.info.em_force_N == 0.0:
            continue
        scale = float(np.mean(pressure_ratio(fit.variant.system, d.info, spec.options) ** v["beta"]))
        dirs = set(spec.options.get("directions") or ("x", "y"))
        directions = fit.variant.settings.directions
        for name in out:
            if directions.get(name) in dirs:
                out[name] *= scale
    return out
