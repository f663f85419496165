"""FE polish of the surface optimum, and modal solves on mesh-extrapolated frequencies.

The response surfaces give each state a first optimum; the polish refines it by Gauss-Newton on the
full FE model (or on the verified reduced-order model), see :func:`fe_polish`.  With
``mesh.extrapolate_edges`` the polish fits the frequencies extrapolated over the mesh's
edge-refinement levels (:mod:`jointid.fe.extrapolate`, docs/reconstruction.md, "Mesh
extrapolation"): :func:`extrapolated_polish` repeats it with the factors taken at its last optimum
until they settle.

* :class:`PolishFit` - what the polish fits (measured modes, bounds, noise, visibility rule);
* :func:`fe_polish` - the Gauss-Newton polish itself, on any solve function;
* :func:`log_jacobian` - exact modal sensitivities ``d ln f / d log10 theta``;
* :func:`solve_point` - modal solve of a cached model at joint parameters (Hz, shapes at the
  measuring points);
* :func:`edge_limit_at` - the mesh-extrapolated frequencies of a model at joint parameters;
* :func:`polish_on_model` / :func:`polish_optimum` - the polish on a model / on the model files of
  a run;
* :func:`extrapolated_polish` - the polish again on mesh-extrapolated frequencies;
* :func:`corrected` - a solve function with each frequency scaled by its extrapolation factor.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from jointid.config.typed import ModelSpec
from jointid.correlate.mac import mac
from jointid.correlate.pairing import pair_by_frequency, pair_by_shapes
from jointid.errors import DataError
from jointid.fe.certificate import reduced_certificate
from jointid.fe.describe import describe_modes
from jointid.fe.extrapolate import FrequencyCorrection, edge_limit
from jointid.fe.modal import SURVEY_TOL, release_heap, solve_model
from jointid.fe.fem import Model
from jointid.fe.model import base_coefficients, joint_terms, load_model
from jointid.fe.reduced import ReducedSolver
from jointid.identification.rom import ROM, load_rom
from jointid.identification.polish_fit import PolishFit
from jointid.identification.polish_shapes import block_covariance, shape_rows, shape_sensitivity, start_uncertainty
from jointid.identification.visibility import misfit_table
from jointid.progress import Work, stamp

__all__ = ["EXTRAPOLATION_PASSES", "EXTRAPOLATION_SETTLED", "PolishFit", "corrected", "edge_limit_at",
           "extrapolated_polish", "fe_polish", "log_jacobian", "model_sizes", "polish_on_model", "polish_optimum",
           "settled_below", "solve_point"]

EXTRAPOLATION_PASSES = 3  # polishes on extrapolated frequencies, each with factors taken at the last optimum
EXTRAPOLATION_SETTLED = 2e-3  # the smallest threshold of settled_below (relative)
STEP_TOL = 1e-4  # the polish stops once a step moves no log10 parameter by more than this


def settled_below(sigma_rel) -> float:
    """The first-order change of the mesh factors over a polish below which they count as settled:
    a third of the smallest stated frequency uncertainty ``sigma_rel`` (relative; the mesh's share of
    the error budget), and never less than :data:`EXTRAPOLATION_SETTLED`.  The change left after a
    pass is of second order, so the factors' error stays well below that."""
    return max(EXTRAPOLATION_SETTLED, float(np.min(sigma_rel)) / 3)


def log_jacobian(stiffness: dict, phi: np.ndarray, lam: np.ndarray, terms: list[dict[str, float]],
                 theta: np.ndarray) -> np.ndarray:
    """``d ln f / d log10 theta_i`` of mass-normalised modes ``phi`` (columns) with eigenvalues ``lam``.

    Exact modal sensitivities: ``d lambda / d theta_i = sum_t c phi^T K_t phi`` over the stiffness
    terms ``terms[i] = {name: c}`` of parameter i (``stiffness[name]`` the matrices, in the space of
    ``phi``); ``d ln f = d lambda / (2 lambda)``.  Returns ``(n_modes, n_params)``.
    """
    J = np.empty((phi.shape[1], len(theta)))
    for i, (tm, th) in enumerate(zip(terms, theta)):
        dlam = sum(c * np.einsum("ij,ij->j", phi, stiffness[t] @ phi) for t, c in tm.items())
        J[:, i] = dlam * th * np.log(10) / (2 * lam)
    return J


def fe_polish(solve, theta0: np.ndarray, names: list[str], terms: list[dict[str, float]], fit: PolishFit, *,
              repair_min_Hz: float | None = None, max_iter: int = 8, log=print):
    # long: one Gauss-Newton loop whose every iterate re-pairs, scores the misfits and keeps the best
    """Refine the surface optimum with the full FE model (Gauss-Newton on log10 parameters).

    ``solve(theta) -> (freqs_Hz (n,), shapes (labels, n), phi (dofs, n), K_terms[, extra])`` gives the FE
    modes (``extra`` ``(n, n_params)``: a part of ``d ln f / d log10 theta`` beyond ``phi``'s);
    ``fit`` (:class:`PolishFit`) holds the measured modes, the bounds, the weights and the noise;
    each measured mode follows the FE mode with the highest MAC to its current shape (starting from
    ``fit.ref_shapes``, the tracked reference shapes of the paired modes). Frequency derivatives are
    exact modal sensitivities ``d lambda / d theta_i = phi^T K_i phi`` (mass-normalised phi).
    ``terms[i]`` maps stiffness term names to the coefficient per unit of parameter i.
    With ``repair_min_Hz`` (frequency-only data) the measured modes are re-paired at every iterate by
    the order-preserving frequency assignment among FE modes above that frequency, the same rule as
    on the surfaces; the best iterate is kept.  ``fit.rule``
    (:class:`jointid.identification.visibility.VisibilityRule`, its labels those of the solve's
    shapes): FE modes the test would clearly have seen that no measured mode takes are misfits, extra
    residuals with exact sensitivities, and the frequency re-pairing pays for leaving them unpaired.

    Returns ``dict(theta, f_fe, index, mac, jacobian_log10, cov_log10, iterations, unpaired_visible,
    chi2, dof)``, and with shape rows (``fit.shapes``) ``shape_chi2, shape_dof, shape_c_hat,
    shape_uncertainty, cluster_factor`` (``jacobian_log10`` is always the frequency rows', relative).
    """
    f_meas, rule, sigma_rel = fit.f_meas_Hz, fit.rule, fit.sigma_rel
    lo, hi = np.log10(fit.lower_N_per_m3), np.log10(fit.upper_N_per_m3)
    y = np.log10(np.asarray(theta0, float))
    w = np.ones(len(f_meas)) if fit.weights is None else np.asarray(fit.weights, float)
    shapes_now = np.asarray(fit.ref_shapes)
    with_shapes = fit.has_shapes and repair_min_Hz is None  # shape rows: a block of their own (polish_shapes)
    eps = fit.shape_sigma_rel
    history = []
    best = None
    for it in range(max_iter + 1):
        freqs, shapes, phi, stiff, *extra = solve(10 ** y)
        vis = rule.visibility(shapes, freqs) if rule is not None else None
        if repair_min_Hz is not None:
            cand = np.flatnonzero(freqs >= repair_min_Hz)
            index = (cand[pair_by_frequency(f_meas, freqs[cand])] if rule is None
                     else rule.pair_by_frequency(f_meas, freqs, vis, cand))
            macs = np.array([float(mac(shapes_now[:, i], shapes[:, j])[0, 0]) for i, j in enumerate(index)])
        else:
            index, macs = pair_by_shapes(shapes_now, shapes, threshold=0.2)
        if np.any(index < 0):
            raise DataError("FE polish: a paired mode could not be followed by MAC — widen the DOE "
                            "or check the pairing in results/identify/<state>/params.json")
        pen, tgt = rule.misfits(index, freqs, vis, f_meas) if rule is not None else (np.zeros(0, int), np.zeros(0))
        rows = np.concatenate([index, pen]).astype(int)
        f, f_all = freqs[index], freqs[rows]
        target = np.concatenate([f_meas, tgt])
        sw = np.sqrt(np.concatenate([w, np.ones(pen.size)]))
        r = sw * (f_all - target) / target
        # d(f / f_target) / d log10 theta = (f / f_target) d ln f / d log10 theta
        dlnf = log_jacobian(stiff, phi[:, rows], (2 * np.pi * f_all) ** 2, terms, 10 ** y)
        if extra:  # a part of d ln f / d log10 theta that the solve knows beyond phi (e.g. a correction factor's)
            dlnf = dlnf + np.asarray(extra[0])[rows]
        J = (sw * f_all / target)[:, None] * dlnf
        n_freq, modes = len(r), np.zeros(0, int)
        if with_shapes:  # frequency rows in units of their noise, then the shape rows
            if eps is None:
                eps = start_uncertainty(fit.shapes, shapes, index)
            dshape = shape_sensitivity(stiff, phi, (2 * np.pi * freqs) ** 2, shapes, terms, 10 ** y, index)
            rs, Js, modes = shape_rows(fit.shapes, eps, shapes, index, dshape)
            r, J = np.concatenate([r / sigma_rel, rs]), np.vstack([J / sigma_rel, Js])
        history.append(float(r @ r))
        if best is None or history[-1] < best[0]:
            best = (history[-1], y.copy(), f.copy(), index.copy(), macs.copy(), J.copy(), np.array(freqs),
                    None if vis is None else vis.copy(), r.copy(), n_freq, modes)
        rel = r[:n_freq] * (sigma_rel if with_shapes else 1.0)
        log(f"  FE polish it {it}: max |error| {100 * np.abs(rel[:len(f_meas)] / np.sqrt(w)).max():.3f} %"
            + (f" (+{pen.size} unpaired visible, max misfit {100 * np.abs(rel[len(f_meas):]).max():.2f} %)"
               if pen.size else "") + (f", shapes chi2 {float(r[n_freq:] @ r[n_freq:]):.1f} for {len(r) - n_freq} rows"
                                      if with_shapes else "")
            + ", " + ", ".join(f"{n}={10**v:.4g}" for n, v in zip(names, y)))
        shapes_now = shapes[:, index]
        if it == max_iter:
            break
        # Levenberg-Marquardt step, clipped to the bounds
        lam = 1e-3 * np.trace(J.T @ J) / len(y)
        step = -np.linalg.solve(J.T @ J + lam * np.eye(len(y)), J.T @ r)
        y_new = np.clip(y + step, lo, hi)
        if np.max(np.abs(y_new - y)) < STEP_TOL:
            y = y_new
            break
        y = y_new
    chi2_raw, y, f, index, macs, J, freqs, vis, r, n_freq, modes = best
    blocks = {}
    if with_shapes:  # each block at its own lack of fit, the cluster-robust check (polish_shapes)
        blocks = block_covariance(J, r, n_freq, len(y), modes)
        cov = blocks.pop("cov")
        chi2_raw = blocks["chi2"] * sigma_rel ** 2  # the frequency block's, as without shapes
        blocks.update(shape_uncertainty=eps, dof=None)
        J = J[:n_freq] * sigma_rel  # the frequency rows' Jacobian, relative (as without shapes)
    else:
        cov = sigma_rel**2 * np.linalg.pinv(J.T @ J)
    band = (np.min(f_meas), np.max(f_meas))
    unpaired = [float(freqs[j]) for j in range(len(freqs))
                if band[0] <= freqs[j] <= band[1] and j not in set(index.tolist())]
    visible = [] if rule is None else misfit_table(rule, index, freqs, vis, f_meas)
    return {"theta": 10 ** y, "f_fe": f, "index": index, "mac": macs, "jacobian_log10": J,
            "unpaired_in_band_Hz": unpaired, "unpaired_visible": visible,
            "chi2": chi2_raw / sigma_rel**2, "dof": max(1, len(f_meas) - len(y)),
            "cov_log10": cov, "iterations": it, "cost_history": history,
            "on_bound": [n for n, v, a, b in zip(names, y, lo, hi) if min(v - a, b - v) < 1e-3],
            **{k: v for k, v in blocks.items() if k not in ("chi2", "dof")}}


def polish_intervals(polish: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """``(scale, ci95_low, ci95_high)`` of a polish record (:func:`fe_polish`): the Gauss-Newton covariance
    in log10, widened by ``scale = max(1, sqrt(chi2 / dof))``: when the fit is worse than the stated
    frequency uncertainty, a model error, not the noise, sets the scatter.  With shape rows in the fit
    (:mod:`jointid.identification.polish_shapes`) each block is widened by its own lack of fit inside
    ``cov_log10``, and ``scale`` is 1."""
    theta = np.asarray(polish["theta"], float)
    scale = float(max(1.0, np.sqrt(polish["chi2"] / polish["dof"])))
    if polish.get("shape_dof"):  # with shape rows the covariance already holds each block's lack of fit
        scale = 1.0
    sd = scale * np.sqrt(np.clip(np.diag(polish["cov_log10"]), 0, None))
    return scale, theta * 10 ** (-1.96 * sd), theta * 10 ** (1.96 * sd)


def _log(msg: str) -> None:
    print(stamp(msg), flush=True)


def solve_point(spec: ModelSpec, model, theta: dict[str, float], n_modes: int | None = None, describe: bool = True,
                certify: bool = False, tol: float = 0.0):
    """Modal solve of the cached model at joint parameters ``theta`` (N/m^3).

    ``spec``: the model's description (its coefficients and solver options); ``n_modes``: default
    ``spec.solver.n_modes``; ``describe``: with the modes' energy table; ``certify``: with a Sturm
    check of its completeness (``modes.sturm``, :func:`jointid.fe.modal.solve_model`); ``tol``: the Lanczos
    tolerance (:data:`jointid.fe.modal.SURVEY_TOL` for a mesh-error estimate).

    Returns ``(freqs_Hz, shapes at measuring points (n_labels, n_modes), description table, modes)``.
    """
    s = spec.solver
    kc, mc = base_coefficients(spec, model, theta)
    modes = solve_model(model, kc, mc, n_modes or s.n_modes, shift_Hz=s.shift_Hz, backend=s.backend,
                        certify=certify, tol=tol)
    shapes = model.probe @ modes.phi
    desc = None
    if describe:
        desc = describe_modes(model, modes.phi, kc, mc)
    return modes.freqs_Hz, shapes, desc, modes


def polish_optimum(spec: ModelSpec, names: list[str], matrices, theta0, fit: PolishFit, *, rom=None,
                   correction=None):
    """Gauss-Newton refinement of the surface optimum on the full FE model (or the ROM file ``rom``).

    ``names``: the joint parameters (the surface model's), ``matrices`` the cached model file (or the
    :class:`jointid.fe.fem.Model` itself), ``theta0`` the surface optimum (N/m^3); the rest as in
    :func:`polish_on_model`.
    """
    model = load_rom(rom) if rom else _session_model(matrices)
    return polish_on_model(spec, model, names, theta0, fit, correction=correction)


_SESSION: dict = {}
"""The model file (or model) last polished on, its model and its reduced solver (:func:`_session_model`)."""


def forget_session() -> None:
    """Start the next polish afresh: a new reduced solver, as in a new process (the rule ``identify`` of each
    state runs in its own)."""
    _SESSION.clear()


def _session_key(matrices) -> str:
    """The session's key of a model file, or of a model object (:class:`jointid.fe.fem.Model`) by identity."""
    return f"model@{id(matrices)}" if isinstance(matrices, Model) else str(matrices)


def _session_model(matrices):
    """The model of ``matrices`` (a model file, or the model itself), the same object for every polish of
    this process on it, so that the polish on extrapolated frequencies reuses the reduced solver of the
    first polish (its basis already spans the neighbourhood; every answer is still certified by its
    full-space residual) instead of factorising and seeding a new one."""
    key = _session_key(matrices)
    if _SESSION.get("path") != key:
        _SESSION.clear()
        _SESSION.update(path=key, model=matrices if isinstance(matrices, Model) else load_model(matrices))
    return _SESSION["model"]


def extrapolated_polish(spec: ModelSpec, state: str, names: list[str], matrices, edge_models, polish: dict,
                        fit: PolishFit, *, rom=None):
    """The polish again on mesh-extrapolated frequencies, until their factors are those of its optimum.

    ``edge_models``: the models with one and two more edge levels, or functions that build them
    (:func:`jointid.fe.model.edge_level_builders`: each built when its turn comes and dropped after
    its solve); ``polish``: the polish on
    the base mesh; the rest as in :func:`polish_optimum`.

    The factors are taken at the current optimum (first the base mesh's), with their first-order
    dependence on the parameters, and the polish is repeated with them.  Should they change by more
    than :func:`settled_below` (relative, to first order) over the polish's step, where their
    second-order change might matter, they are taken again at the new optimum (at most
    ``EXTRAPOLATION_PASSES`` passes).  Returns ``(record for params.json, the last polish)``.
    """
    say = lambda m: _log(f"identify[{state}]: {m}")  # noqa: E731
    base = matrices if isinstance(matrices, Model) else partial(load_model, matrices)
    models = [base, *edge_models]  # peak memory: one level at a time
    theta_mesh = dict(zip(names, map(float, polish["theta"])))
    passes, settled = [], settled_below(fit.sigma_rel)
    for k in range(EXTRAPOLATION_PASSES):
        at = np.asarray(polish["theta"], float)
        say(f"mesh extrapolation over the edge levels at {'the base-mesh optimum' if k == 0 else 'the new optimum'}")
        lim = edge_limit_at(spec, models, dict(zip(names, map(float, at))), log=say, sensitivities=True,
                            base=None if rom else certified_base(spec, names, matrices, at))
        shown = [i for i in range(lim.limit_Hz.size) if lim.levels_Hz[0, i] >= spec.solver.min_freq_Hz]
        say("extrapolated: " + ", ".join(f"{lim.levels_Hz[0, i]:.1f}->{lim.limit_Hz[i]:.1f} Hz" for i in shown))
        say("polish on the extrapolated frequencies")
        polish = polish_optimum(spec, names, matrices, at, fit, rom=rom,
                                correction=FrequencyCorrection.from_limit(lim, at))
        moved = float(np.max(np.abs(polish["theta"] / at - 1)))
        drift = float(np.max(np.abs(lim.slope[shown] @ np.log10(polish["theta"] / at))))
        passes.append({"factors_at": dict(zip(names, map(float, at))), "max_parameter_change": moved,
                       "max_factor_change_first_order": drift, "settled_below": settled})
        say(f"pass {k + 1}: the polish moved the parameters by at most {100 * moved:.2f} %, the factors by "
            f"{100 * drift:.3f} % (first order)")
        if drift < settled:
            break
    else:
        say(f"warning: the factors did not settle in {EXTRAPOLATION_PASSES} passes (last change {100 * drift:.3f} %)")
    odd = [f"{lim.levels_Hz[0, i]:.0f} Hz ({lim.status[i]})" for i in shown
           if lim.status[i] in ("not asymptotic", "lost")]
    if odd:
        say("kept the finest mesh's frequency (no geometric sequence): " + ", ".join(odd))
    record = {"theta_base_mesh": theta_mesh, "n_dofs": lim.n_dofs, "passes": passes,
              "modes": lim.table().to_dict(orient="list"), "not_extrapolated": odd,
              "correction": {**FrequencyCorrection.from_limit(lim, at).record(), "names": list(names)}}
    return record, polish


def polish_on_model(spec: ModelSpec, model, names: list[str], theta0, fit: PolishFit, *, max_iter: int = 8,
                    log=None, correction=None):
    """FE polish (:func:`fe_polish`) of joint parameters ``names`` on ``model``, from ``theta0`` (N/m^3).

    ``model`` is the full FE model (:class:`jointid.fe.fem.Model`) or a reduced-order model
    (:class:`jointid.identification.rom.ROM`, evaluated in its generalised coordinates, where the sensitivities
    ``y^T Kr_i y`` are exact for the reduced model).  On the full model the iterates are solved by a
    :class:`jointid.fe.reduced.ReducedSolver` started at ``theta0`` (the exact modes there and their
    responses to each parameter, enriched wherever a Ritz pair's full-space residual says its
    eigenvalue is off by more than 1e-6): full-FE answers for one factorisation instead of one per
    iterate.  ``fit`` (:class:`PolishFit`): ``ref_shapes`` ``(n_labels, n_measured)`` are the shapes
    the measured modes follow by MAC; with ``repair`` (frequency-only data) the modes are re-paired by
    frequency (above ``spec.solver.min_freq_Hz``) at every iterate instead.  ``correction`` (:class:`jointid.fe.extrapolate.FrequencyCorrection`) scales each mode's
    frequency by the mesh-extrapolation factor of the mode it continues.  ``fit.rule``
    (:class:`jointid.identification.visibility.VisibilityRule`): modes the test would clearly have
    seen count as misfits when no measured mode takes them.  On the full model the result carries
    ``certificate`` (:func:`jointid.fe.certificate.reduced_certificate` at the returned optimum).
    """
    jt = joint_terms(spec.joints, spec.mesh_file)
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    n_modes = spec.solver.n_modes
    if isinstance(model, ROM):
        reduced_terms = dict(zip(model.k_names, model.k_terms))

        def solve(theta):
            freqs, shapes, y = model.solve_theta(dict(zip(names, theta)), n_modes, return_coords=True)
            return freqs, shapes, y, reduced_terms
    else:
        rs = _reduced_solver(spec, model, names, theta0, terms, n_modes)
        rs.log = log or _log  # a failed certificate's fallback to the full solve is logged

        def solve(theta):
            sol = rs.solve(*base_coefficients(spec, model, dict(zip(names, theta))), n_modes)
            return sol.freqs_Hz, sol.shapes, rs.full_phi(sol), model.stiffness

    if correction is not None:
        solve = corrected(solve, correction)
    out = fe_polish(solve, theta0, names, terms, fit, repair_min_Hz=spec.solver.min_freq_Hz if fit.repair else None,
                    max_iter=max_iter, log=log or _log)
    if not isinstance(model, ROM):  # the residual check of the returned modes (the ROM's: rule rom)
        kc, mc = base_coefficients(spec, model, dict(zip(names, out["theta"])))
        out["certificate"] = reduced_certificate(rs, kc, mc, n_modes)
    return out


def _reduced_solver(spec: ModelSpec, model, names, theta0, terms, n_modes):
    """A :class:`ReducedSolver` of ``model`` started at ``theta0``; the one built before for the same
    model object and parameters when there is one (see :func:`_session_model`)."""
    key = (id(model), tuple(names), n_modes)
    if _SESSION.get("model") is model and _SESSION.get("solver_key") == key:
        return _SESSION["solver"]
    kc0, mc0 = base_coefficients(spec, model, dict(zip(names, theta0)))
    rs = ReducedSolver(model, kc0, mc0, n_modes, [(t, {}) for t in terms], shift_Hz=spec.solver.shift_Hz,
                       backend=spec.solver.backend)
    if _SESSION.get("model") is model:
        _SESSION.update(solver_key=key, solver=rs)
    return rs


def corrected(solve, correction):
    """``solve`` with each mode's frequency scaled by its mesh-extrapolation factor (in ascending order).

    A factor adds its own ``d ln c / d log10 theta`` to the mode's ``d ln f / d log10 theta``, which
    the polish gets as a fifth return value; :func:`log_jacobian` computes the
    mesh's part as ``phi^T K' phi / (2 lambda)`` from the frequency it is given, so ``phi`` is scaled
    by the same factor to keep that part exact.
    """
    def solve_corrected(theta):
        freqs, shapes, phi, stiff = solve(theta)
        c, grad = correction.factors(shapes, theta)
        order = np.argsort(freqs * c, kind="stable")
        out = (freqs * c)[order], shapes[:, order], (phi * c)[:, order], stiff
        return out if grad is None else (*out, grad[order])  # + the factors' own d ln / d log10 theta

    return solve_corrected


SOLVE_COST_EXPONENT = 1.3  # a modal solve's time grows about as DOFs^1.3 (benchmark d)


def edge_limit_at(spec: ModelSpec, models: list, theta: dict[str, float], log=None, base=None,
                  sensitivities: bool = False, sizes: list[int] | None = None):
    """:class:`jointid.fe.extrapolate.EdgeLimit` of the modes of ``models[0]`` at ``theta`` (N/m^3);
    ``spec``: the model's description (coefficients, solver options; the same for every mesh); ``models``:
    the base mesh and the meshes with one (two) more edge levels (a few more modes are solved on
    those, so that the highest base modes find their partner), each a model or a function that
    builds one (built when its turn comes and dropped after its solve); ``base``: the base mesh's
    ``(freqs_Hz, shapes)`` at ``theta`` when already solved (with ``sensitivities``: ``(freqs_Hz,
    shapes, log-Jacobian)``, :func:`log_jacobian`); ``sensitivities``: with the factors'
    first-order dependence on ``theta`` (exact modal sensitivities on each mesh); ``sizes``: the DOFs
    of each mesh when known beforehand, for the time-left estimate of the progress lines (each solve
    weighted by DOFs^1.3; without them every level counts alike)."""
    names = list(theta)
    jt = joint_terms(spec.joints, spec.mesh_file)
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    solves = []
    todo = [k for k in range(len(models)) if not (k == 0 and base is not None)]
    work = Work([float(sizes[k]) ** SOLVE_COST_EXPONENT if sizes else 1.0 for k in todo])
    for k, model in enumerate(models):
        if k and callable(model):  # a level built here: the one before it is given back first
            release_heap()
        model = model() if callable(model) else model
        if k == 0 and base is not None:
            solves.append((base[0], base[1], model.n_dofs, *base[2:]))
            continue
        f, s, _, modes = solve_point(spec, model, theta, n_modes=spec.solver.n_modes + (2 if k else 0),
                                     describe=False, tol=SURVEY_TOL)  # an estimate of the mesh error, no certificate
        J = (log_jacobian(model.stiffness, modes.phi, modes.omega2, terms, np.array([theta[n] for n in names]))
             if sensitivities else None)
        solves.append((f, s, model.n_dofs, J))
        if log:
            log(f"edge level +{k}: {model.n_dofs} DOFs solved {work.done()}")
        del model
    return edge_limit(solves, ratio=spec.mesh.edge_ratio)


def certified_base(spec: ModelSpec, names: list[str], matrices, theta: np.ndarray):
    """Base mesh ``(freqs_Hz, shapes, log-Jacobian)`` at ``theta`` from this process's certified polish solver."""
    if _SESSION.get("path") != _session_key(matrices) or (rs := _SESSION.get("solver")) is None:
        return None  # no polish solver of this very model file in this process
    model = _SESSION["model"]
    sol = rs.solve(*base_coefficients(spec, model, dict(zip(names, map(float, theta)))), spec.solver.n_modes)
    phi, jt = rs.full_phi(sol), joint_terms(spec.joints, spec.mesh_file)
    if max(spec.mesh.edge_extra_levels) > 1:  # the second level's solve needs the memory (0.3 GB): released, a
        rs.release_factor()  # later enrichment factorises again; beside the first level's only (default), kept
    J = log_jacobian(model.stiffness, phi, sol.lam, [{t: 1.0 for t in jt[n]} for n in names], np.asarray(theta, float))
    return sol.freqs_Hz, model.probe @ phi, J


def model_sizes(paths: list) -> list[int]:
    """DOFs of the model files ``paths`` (each only mapped, not read: a few milliseconds)."""
    return [load_model(p).n_dofs for p in paths]
