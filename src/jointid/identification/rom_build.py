"""Building and verifying the parametric reduced-order model (:mod:`jointid.identification.rom`).

Training at points of the coded joint-parameter box (:mod:`jointid.identification.doe`), the
M-orthonormal basis and its projected terms (``_Builder``), and the greedy error control: random
interior candidates ranked by :func:`residual_indicator`, the worst solved in full and their modes
added while the relative frequency error exceeds the tolerance.  See :mod:`jointid.identification.rom`
for the method.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.linalg as sla

from jointid.config.typed import ModelSpec, SolverOptions
from jointid.errors import ModelError, NumericalWarning
from jointid.fe.modal import TWO_PI, factorize, free_dofs, restrict, solve_model
from jointid.fe.model import base_coefficients, joint_terms
from jointid.geometry.points import dof_labels
from jointid.identification.doe import to_physical
from jointid.identification.rom import ROM, frequency_error
from jointid.identification.rom_options import RomOptions

__all__ = ["RomOptions", "build_rom", "training_points", "residual_indicator"]


def training_points(n_params: int, kind: str = "corners") -> np.ndarray:
    """Coded training points in ``[-1, 1]^p``: ``corners`` (2^p corners + centre) or ``star``
    (centre + the 2p face centres)."""
    if kind == "corners":
        pts = [np.zeros(n_params)] + [np.array(c, float) for c in itertools.product((-1.0, 1.0), repeat=n_params)]
    elif kind == "star":
        pts = [np.zeros(n_params)]
        for i in range(n_params):
            for s in (-1.0, 1.0):
                e = np.zeros(n_params)
                e[i] = s
                pts.append(e)
    else:
        raise ModelError(f"rom: training points '{kind}' are unknown — use corners, star or an array")
    return np.array(pts)


class _Builder:
    """Basis, projections and bookkeeping during :func:`build_rom`."""

    def __init__(self, model, m_ref: dict, rank_rtol: float):
        self.model = model
        self.m_ref = m_ref
        self.Mref = model.M(m_ref)
        self.rank_rtol = rank_rtol
        self.V = np.zeros((model.n_dofs, 0))
        self.k_names = ["K0"] + [n for n in model.stiffness if n != "K0"]
        self.m_names = ["M0"] + [n for n in model.mass if n != "M0"]
        self.k_terms = np.zeros((len(self.k_names), 0, 0))
        self.m_terms = np.zeros((len(self.m_names), 0, 0))

    def add(self, W: np.ndarray) -> int:
        """M-orthonormalise ``W`` against the basis and itself; append what is new; return count."""
        V, M = self.V, self.Mref
        norms = np.sqrt(np.einsum("ij,ij->j", W, M @ W))
        W = W / np.where(norms > 0, norms, 1.0)
        for _ in range(2):  # classical Gram-Schmidt against the basis, twice
            if V.shape[1]:
                W = W - V @ (V.T @ (M @ W))
        G = W.T @ (M @ W)
        G = 0.5 * (G + G.T)
        s, U = np.linalg.eigh(G)
        keep = s > self.rank_rtol * max(1.0, s.max())
        if not keep.any():
            return 0
        Q = W @ (U[:, keep] / np.sqrt(s[keep]))
        for _ in range(2):  # re-orthonormalise (Cholesky QR in the M inner product)
            if V.shape[1]:
                Q = Q - V @ (V.T @ (M @ Q))
            G = Q.T @ (M @ Q)
            L = np.linalg.cholesky(0.5 * (G + G.T))
            Q = sla.solve_triangular(L, Q.T, lower=True).T
        self._project(Q)
        self.V = np.hstack([V, Q])
        return Q.shape[1]

    def _project(self, Q: np.ndarray) -> None:
        V = self.V
        r0, r1 = V.shape[1], V.shape[1] + Q.shape[1]
        for attr, names, terms in (("k_terms", self.k_names, self.model.stiffness),
                                   ("m_terms", self.m_names, self.model.mass)):
            old = getattr(self, attr)
            new = np.zeros((len(names), r1, r1))
            new[:, :r0, :r0] = old
            for i, name in enumerate(names):
                AQ = terms[name] @ Q
                new[i, r0:, r0:] = 0.5 * ((Q.T @ AQ) + (Q.T @ AQ).T)
                if r0:
                    cross = V.T @ AQ
                    new[i, :r0, r0:] = cross
                    new[i, r0:, :r0] = cross.T
            setattr(self, attr, new)


def _full_solve(model, kc, mc, n, solver: SolverOptions):
    return solve_model(model, kc, mc, n, shift_Hz=solver.shift_Hz, backend=solver.backend)


def _inverse_iterates(b: "_Builder", model, kc, mc, n, solver: SolverOptions, n_inverse: int, labels) -> int:
    """Improve the current ROM's ``n`` lowest Ritz vectors at ``(kc, mc)`` by ``n_inverse`` block
    inverse iterations with the full ``K - sigma M`` (one factorisation); add them to the basis.
    Returns the number of basis vectors added."""
    shift = float(solver.shift_Hz)
    sigma = -abs(TWO_PI * shift) ** 2 if shift <= 0 else (TWO_PI * shift) ** 2
    free = free_dofs(model.n_dofs, model.fixed)
    K, M = model.K(kc), model.M(mc)
    A = restrict(K - sigma * M, free)
    try:
        fac = factorize(A, solver.backend, model.ordering)
    except Exception as exc:
        raise ModelError(f"rom: factorisation of K - sigma*M failed at a training point ({exc}) — check "
                         "the joint stiffness bounds and supports, or use solver.shift_Hz < 0") from None
    added = 0
    try:
        for _ in range(max(1, int(n_inverse))):
            rom = _assemble(b, model, n, {}, labels)
            _, _, y = rom.solve(kc, mc, n, check=False, return_coords=True)
            X = b.V @ y
            W = np.zeros_like(X)
            W[free] = fac.solve(np.ascontiguousarray((M @ X)[free]))
            added += b.add(W)
    finally:
        fac.free()
    return added


def residual_indicator(model, rom: ROM, k_coeffs: dict, m_coeffs: dict, n_modes: int | None = None,
                       V: np.ndarray | None = None) -> np.ndarray:
    """Relative residual ``||K phi - w^2 M phi|| / ||K phi||`` (free DOFs) of each ROM mode.

    A cheap a-posteriori error indicator (one sparse product per active term, no factorisation):
    the relative frequency error behaves like a constant times its square.  Needs the basis (``V`` or
    ``rom.basis``).  Returns shape ``(n_modes,)``.
    """
    V = rom.basis if V is None else V
    f, _, y = rom.solve(k_coeffs, m_coeffs, n_modes, check=False, return_coords=True)
    phi = V @ y
    Kp = model.stiffness["K0"] @ phi
    for name, c in k_coeffs.items():
        if c != 0.0:
            Kp += c * (model.stiffness[name] @ phi)
    Mp = model.mass["M0"] @ phi
    for name, c in m_coeffs.items():
        if c != 0.0:
            Mp += c * (model.mass[name] @ phi)
    R = Kp - Mp * (TWO_PI * f) ** 2
    if len(model.fixed):
        R[model.fixed] = 0.0
        Kp[model.fixed] = 0.0
    return np.linalg.norm(R, axis=0) / np.maximum(np.linalg.norm(Kp, axis=0), 1e-300)


def build_rom(model, spec: ModelSpec, points="corners", options: RomOptions | None = None, *,
              extra_points: list[tuple[dict, dict]] | None = None, labels: list[str] | None = None,
              candidates=None, progress=None) -> ROM:
    """Build and verify a parametric ROM of ``model`` over the joint-parameter box of ``spec``.

    Greedy error control: ``n_candidates`` random interior points of the coded box are ranked by
    :func:`residual_indicator`; in each round the ``n_verify`` worst ones are solved in full and the
    true relative frequency errors of the tracked modes are measured.  If one exceeds ``tol``, the
    full modes of the failing points join the basis and the next round starts; otherwise the ROM is
    verified.

    Parameters
    ----------
    model : jointid.fe.fem.Model
        The assembled affine model (``model.build_model`` or ``model.load_model``).
    spec : ModelSpec
        The model's description: its joints (the box, ``joints.parameters``), coefficients and solver options.
    points : ``"corners"``, ``"star"``, array (n, p) or list of dict
        Training points: coded points in ``[-1, 1]^p`` over ``joints.parameters`` (log coding as in
        :mod:`jointid.identification.doe`) or dicts of joint parameters in N/m^3 (e.g. an identified optimum).
    options : RomOptions, optional
        How the ROM is trained and verified (default :class:`RomOptions`).
    extra_points : list of (k_coeffs, m_coeffs), optional
        Further training points given directly as term coefficients (e.g. effect terms).
    labels : list of str, optional
        Labels of the probe rows (default ``<point>:<dir>`` from ``model.meta['points']``).
    candidates : array (n, p), optional
        Further coded candidate points in ``[-1, 1]^p`` ranked with the random ones, e.g. the points
        where the ROM will be evaluated (a DOE): the error control then also covers them.
    progress : callable, optional
        Called with one line of text per training point and verification round.

    Returns
    -------
    ROM
        ``report['max_error']``: worst tracked relative frequency error at the last round's
        verification points; ``report['verified']``: whether it met ``tol``.  A
        :class:`NumericalWarning` is issued when it did not after ``max_rounds`` rounds.
    """
    opts = options or RomOptions()
    box = _Box(spec, model)
    train = _training_set(box, points, extra_points)
    b = _Builder(model, train[0][1][1], opts.rank_rtol)
    if opts.training not in ("inverse", "modes"):
        raise ModelError(f"rom: training '{opts.training}' is unknown — use inverse or modes")
    run = _Run(model, spec.solver, opts, int(opts.n_modes or spec.solver.n_modes), labels,
               progress or (lambda msg: None))
    _train(b, run, train)
    pool = _candidate_set(box, opts.n_candidates, opts.seed, candidates)
    for theta, (kc, mc) in pool:
        _cover(run.covered, kc, mc)  # the greedy search certifies the box spanned by the candidates
    b.rank_rtol = min(opts.rank_rtol, 1e-10)
    verified, max_err = _enrich(b, run, pool)
    rom = _assemble(b, model, run.n_modes, run.covered, labels, keep_basis=opts.keep_basis)
    run.report.update({"size": rom.size, "max_error": max_err, "verified": bool(verified)})
    rom.report = run.report
    rom.params = _param_map(spec, model, box.names, box.lower, box.upper)
    if not verified:
        warnings.warn(f"rom: relative frequency error {max_err:.2e} still above tol = {opts.tol:.1e} after "
                      f"{len(run.report['rounds'])} enrichment rounds (r = {rom.size}) — raise max_rounds, "
                      "n_extra or n_candidates, or narrow the parameter bounds", NumericalWarning, stacklevel=2)
    return rom


@dataclass
class _Run:
    """One ROM build's inputs and its running records (the covered coefficient ranges, the report)."""

    model: object
    solver: SolverOptions
    opts: RomOptions
    n_modes: int
    labels: list[str] | None
    say: Callable[[str], None]
    covered: dict[str, list[float]] = field(default_factory=dict)
    report: dict = field(default_factory=dict)

    def __post_init__(self):
        self.report = {"n_modes": self.n_modes, "n_train_modes": self.n_train, "tol": self.opts.tol,
                       "training_kind": self.opts.training, "training": [], "rounds": []}

    @property
    def n_train(self) -> int:
        """Modes computed at each training point (tracked + extra)."""
        return self.n_modes + int(self.opts.n_extra)


class _Box:
    """The coded joint-parameter box of ``spec`` (``joints.parameters``, log coding as
    :mod:`jointid.identification.doe`) and the term coefficients at its points."""

    def __init__(self, spec: ModelSpec, model):
        self.spec, self.model = spec, model
        self.names = spec.joints.names
        self.lower = spec.joints.lower_N_per_m3
        self.upper = spec.joints.upper_N_per_m3

    def coefficients(self, x) -> tuple[dict, tuple[dict, dict]]:
        """``(theta, (k_coeffs, m_coeffs))`` at the coded point ``x`` (theta in N/m^3)."""
        theta = dict(zip(self.names, to_physical(np.atleast_2d(x), self.lower, self.upper)[0].tolist()))
        return theta, base_coefficients(self.spec, self.model, theta)


def _training_set(box: _Box, points, extra_points) -> list[tuple[dict, tuple[dict, dict]]]:
    """Training points as ``(theta, (k_coeffs, m_coeffs))`` from ``points`` and ``extra_points``
    (see :func:`build_rom`)."""
    names = box.names
    train: list[tuple[dict, tuple[dict, dict]]] = []
    pts = training_points(len(names), points) if isinstance(points, str) else points
    for pt in pts:
        if isinstance(pt, dict):
            train.append((dict(pt), base_coefficients(box.spec, box.model, dict(pt))))
        else:
            x = np.asarray(pt, float)
            if x.shape != (len(names),):
                raise ModelError(f"rom: training point {x.tolist()} has {x.size} coordinates; "
                                 f"the box has {len(names)} parameters ({', '.join(names)})")
            train.append(box.coefficients(x))
    for kc, mc in extra_points or []:
        train.append(({}, (dict(kc), dict(mc))))
    if not train:
        raise ModelError("rom: no training points — give points='corners' or a list of points")
    return train


def _train(b: _Builder, run: _Run, train: list) -> None:
    """Add every training point to the basis: a full solve at the first (and at all of them for
    ``training="modes"``), block inverse iterations at the others; record each in ``run.report['training']``."""
    n_inverse = run.opts.n_inverse
    for k, (theta, (kc, mc)) in enumerate(train):
        if k == 0 or run.opts.training == "modes":
            added, how = b.add(_full_solve(run.model, kc, mc, run.n_train, run.solver).phi), "full solve"
        else:
            added = _inverse_iterates(b, run.model, kc, mc, run.n_train, run.solver, n_inverse, run.labels)
            how = f"{max(1, int(n_inverse))} inverse iteration(s)"
        _cover(run.covered, kc, mc)
        run.report["training"].append({"theta": theta, "added": added, "how": how})
        run.say(f"rom: training point {k + 1}/{len(train)} ({how}): +{added} vectors (r = {b.V.shape[1]})")


def _cover(covered: dict[str, list[float]], kc: dict, mc: dict) -> None:
    """Widen the covered coefficient ranges ``covered`` (name -> [low, high]) to hold ``kc``, ``mc``."""
    for nme, c in list(kc.items()) + list(mc.items()):
        lo, hi = covered.get(nme, [c, c])
        covered[nme] = [min(lo, c), max(hi, c)]


def _candidate_set(box: _Box, n_candidates: int, seed: int, candidates) -> list:
    """``n_candidates`` random coded points of the box (seeded), then the given ``candidates``, as
    ``(theta, (k_coeffs, m_coeffs))``."""
    names = box.names
    rng = np.random.default_rng(seed)
    coded = rng.uniform(-1.0, 1.0, size=(n_candidates, len(names)))
    if candidates is not None:
        extra = np.atleast_2d(np.asarray(candidates, float))
        if extra.size and extra.shape[1] != len(names):
            raise ModelError(f"rom: candidate points have {extra.shape[1]} coordinates; the box has "
                             f"{len(names)} parameters ({', '.join(names)})")
        coded = np.vstack([coded, extra]) if extra.size else coded
    return [box.coefficients(x) for x in coded]


def _enrich(b: _Builder, run: _Run, candidates: list):
    """Greedy error control of :func:`build_rom`: rank the candidates by the residual indicator, solve
    the ``n_verify`` worst in full, add the modes of those above ``tol``; repeat up to ``max_rounds``.
    Appends each round to ``run.report['rounds']``; returns ``(verified, max_error)``."""
    model, n_modes, n_verify, tol = run.model, run.n_modes, run.opts.n_verify, run.opts.tol
    min_f = float(run.solver.min_freq_Hz)
    verified = n_verify <= 0
    max_err = float("nan")
    for rnd in range(run.opts.max_rounds if n_verify > 0 else 0):
        rom = _assemble(b, model, n_modes, run.covered, run.labels)
        if not candidates:
            break
        eta = np.array([residual_indicator(model, rom, kc, mc, V=b.V).max() for _, (kc, mc) in candidates])
        worst = np.argsort(-eta)[:n_verify]
        checked, failing = [], []
        for i in worst:
            theta, (kc, mc) = candidates[i]
            modes = _full_solve(model, kc, mc, run.n_train, run.solver)
            f_rom, _ = rom.solve(kc, mc, check=False)
            e = frequency_error(f_rom, modes.freqs_Hz[:n_modes], min_f)
            err = float(np.nanmax(e)) if np.isfinite(e).any() else 0.0
            checked.append({"theta": theta, "indicator": float(eta[i]), "max_error": err, "errors": e.tolist()})
            if err > tol:
                failing.append(modes)
        candidates = [c for i, c in enumerate(candidates) if i not in set(worst.tolist())]
        max_err = max(c["max_error"] for c in checked)
        info = {"round": rnd, "r": rom.size, "max_indicator": float(eta.max()), "points": checked,
                "max_error": max_err}
        run.say(f"rom: round {rnd}: r = {rom.size}, worst indicator {eta.max():.1e}, max relative frequency "
                f"error at the {len(checked)} worst candidates {max_err:.2e}")
        run.report["rounds"].append(info)
        if not failing:
            verified = True
            break
        info["added"] = sum(b.add(m.phi) for m in failing)
        if info["added"] == 0:
            break
    return verified, max_err


def _assemble(b: _Builder, model, n_modes, covered, labels, keep_basis=False) -> ROM:
    if labels is None:
        labels = dof_labels(pd.DataFrame(model.meta["points"])) if "points" in model.meta else \
            [f"p{i}" for i in range(model.probe.shape[0])]
    return ROM(k_names=list(b.k_names), m_names=list(b.m_names), k_terms=b.k_terms.copy(),
               m_terms=b.m_terms.copy(), probe=np.asarray(model.probe @ b.V), labels=list(labels),
               n_modes=n_modes, m_ref=dict(b.m_ref), coeff_range={k: list(v) for k, v in covered.items()},
               basis=b.V.copy() if keep_basis else None)


def _param_map(spec: ModelSpec, model, names, lower, upper) -> dict:
    terms = joint_terms(spec.joints, spec.mesh_file)
    kc, mc = base_coefficients(spec, model, None)
    defaults = spec.joints.defaults_N_per_m3()
    k_fixed = dict(kc)
    for name, ts in terms.items():
        for t in ts:
            k_fixed[t] = k_fixed.get(t, 0.0) - defaults.get(name, 0.0)
    k_fixed = {k: v for k, v in k_fixed.items() if abs(v) > 1e-12 * max(1.0, abs(kc.get(k, 0.0)))}
    return {"terms": terms, "defaults": defaults, "k_fixed": k_fixed, "m": mc, "names": names,
            "lower": lower.tolist(), "upper": upper.tolist()}
