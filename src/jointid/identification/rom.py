"""Parametric reduced-order modal model (ROM) of the affine rig model.

The FE model is affine in its term coefficients (:mod:`jointid.fe.fem`)::

    K(k) = K0 + sum_i k_i K_i          M(m) = M0 + sum_j m_j M_j

so once a basis ``V`` (n_dofs x r, r ~ 10^2) is fixed, every term is projected *once*
(``Kr_i = V^T K_i V``) and an evaluation at new coefficients is a small dense generalised
eigenproblem ``Kr(k) y = w^2 Mr(m) y`` (Rayleigh-Ritz), solved with :func:`scipy.linalg.eigh`.

Basis
    Training at a few points of the coded joint-parameter box (default: the centre and its ``2**p``
    corners), stacked and M-orthonormalised against the reference mass matrix (that of the first
    training point); directions that the stack represents to better than ``rank_rtol`` are dropped.
    ``training="modes"``: ``n_modes + n_extra`` mass-normalised modes of a full solve
    (:func:`jointid.fe.modal.solve_modes`) at every training point.  ``training="inverse"`` (default):
    a full solve at the first point only; at every further point the current ROM's Ritz vectors are
    improved by ``n_inverse`` block inverse iterations ``W = (K - sigma M)^-1 M V y`` with one
    factorisation and no Lanczos run, which costs about a third of a full solve and, on the rigs
    tested, reaches the same accuracy (the Ritz vectors are already close, so one step suffices).
Error control (greedy)
    Random interior points of the box (candidates) are ranked by a cheap residual indicator
    (:func:`residual_indicator`, no factorisation); the worst few are solved in full and compared
    with the ROM.  While the relative frequency error of a tracked mode (the lowest ``n_modes`` at or
    above ``min_freq_Hz``) exceeds ``tol`` (default 1e-4), the full modes of the failing points are
    added to the basis and the next round ranks the remaining candidates again.  The history is kept
    in :attr:`ROM.report`.
Accuracy
    Rayleigh-Ritz frequencies are upper bounds of the full ones, mode by mode.  The ROM is verified
    inside the coefficient ranges it was trained and checked on (:attr:`ROM.coeff_range`); outside
    them :meth:`ROM.solve` warns (:class:`jointid.errors.NumericalWarning`).
Speed
    One evaluation costs one dense r x r eigen-solve (~1 ms at r = 100 with single-threaded BLAS;
    set ``OPENBLAS_NUM_THREADS=1`` when running many small evaluations on a shared machine).

Shapes at the measuring points are ``probe @ V @ y`` (rows ``<point>:<direction>`` as
``model.probe``), mass-normalised; the sign is fixed so that the largest component *at the measuring
points* is positive (the full solver fixes it on the whole DOF vector, so compare shapes by MAC).
"""

from __future__ import annotations

import itertools
import json
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from jointid import io
from jointid.identification.doe import to_physical
from jointid.errors import ModelError, NumericalWarning
from jointid.fe.modal import TWO_PI, Modes, factorize, free_dofs, restrict, solve_model
from jointid.fe.model import base_coefficients, joint_terms

__all__ = ["ROM", "build_rom", "training_points", "load_rom", "frequency_error", "residual_indicator",
           "full_modes"]

_FORMAT = "jointid-rom-1"


# ------------------------------------------------------------------ the reduced model
@dataclass
class ROM:
    """Projected affine model: ``Kr(k) = sum k_i Kr_i``, ``Mr(m) = sum m_j Mr_j`` (dense, r x r).

    Attributes
    ----------
    k_names, m_names : list of str
        Term names (``"K0"``, ``"K_top_y"`` ..., ``"M0"``, ``"M_motor"`` ...).
    k_terms, m_terms : ndarray, shape (n_k, r, r), (n_m, r, r)
        Projected terms, in the order of the names; ``K0`` / ``M0`` are always first (coefficient 1).
    probe : ndarray, shape (n_labels, r)
        Measuring-point interpolation of the basis (m per unit generalised coordinate).
    labels : list of str
        Row labels of ``probe`` (``"T01:x"`` ...).
    n_modes : int
        Number of modes returned by :meth:`solve` by default (the tracked modes).
    m_ref : dict
        Mass coefficients at which the basis is M-orthonormal (``Mr(m_ref) = I``).
    coeff_range : dict name -> [low, high]
        Coefficient ranges covered by training and verification points.
    params : dict
        Joint-parameter mapping for :meth:`coefficients`: ``terms`` (parameter -> stiffness terms),
        ``defaults`` (parameter -> N/m^3), ``k_fixed`` (other stiffness coefficients), ``m`` (mass
        coefficients), ``names``, ``lower``, ``upper`` (identified parameters and bounds, N/m^3).
    report : dict
        Build history: training points, verification rounds and errors, basis size.
    basis : ndarray, shape (n_dofs, r), optional
        The basis itself (zero rows at fixed DOFs); needed only by :meth:`expand`.
    """

    k_names: list[str]
    m_names: list[str]
    k_terms: np.ndarray
    m_terms: np.ndarray
    probe: np.ndarray
    labels: list[str]
    n_modes: int
    m_ref: dict[str, float]
    coeff_range: dict[str, list[float]] = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)
    basis: np.ndarray | None = None

    def __post_init__(self):
        self._k_index = {n: i for i, n in enumerate(self.k_names)}
        self._m_index = {n: i for i, n in enumerate(self.m_names)}

    @property
    def size(self) -> int:
        """Number of basis vectors ``r``."""
        return int(self.k_terms.shape[1])

    # ------------------------------------------------------------ evaluation
    def _weights(self, coeffs: dict[str, float] | None, index: dict[str, int], kind: str) -> np.ndarray:
        w = np.zeros(len(index))
        w[0] = 1.0
        unknown = []
        for name, c in (coeffs or {}).items():
            i = index.get(name)
            if i is None:
                if c != 0.0:
                    unknown.append(name)
                continue
            w[i] += c
        if unknown:
            raise ModelError([f"rom: {kind} term '{n}' is not in the reduced model (known: "
                              f"{', '.join(index)}) — rebuild the ROM from a model that has it"
                              for n in unknown])
        return w

    def _check_range(self, kc: dict, mc: dict) -> None:
        out = []
        for name, c in list(kc.items()) + list(mc.items()):
            lo, hi = self.coeff_range.get(name, (0.0, 0.0))
            tol = 1e-9 * max(abs(lo), abs(hi), 1e-300)
            if c < lo - tol or c > hi + tol:
                out.append(f"{name} = {c:.4g} (verified {lo:.4g} .. {hi:.4g})")
        if out:
            warnings.warn("rom: evaluated outside the verified coefficient range: " + "; ".join(out)
                          + " — accuracy is not guaranteed there; rebuild the ROM with points covering it",
                          NumericalWarning, stacklevel=3)

    def reduced_matrices(self, k_coeffs: dict[str, float], m_coeffs: dict[str, float] | None = None):
        """Dense ``(Kr, Mr)`` (r x r) at the given coefficients (``Mr`` is None at ``m_ref``)."""
        wk = self._weights(k_coeffs, self._k_index, "stiffness")
        Kr = np.tensordot(wk, self.k_terms, axes=1)
        mc = self.m_ref if m_coeffs is None else m_coeffs
        same = set(k for k, v in mc.items() if v) == set(k for k, v in self.m_ref.items() if v) and all(
            mc.get(k, 0.0) == v for k, v in self.m_ref.items())
        Mr = None if same else np.tensordot(self._weights(mc, self._m_index, "mass"), self.m_terms, axes=1)
        return Kr, Mr

    def solve(self, k_coeffs: dict[str, float], m_coeffs: dict[str, float] | None = None,
              n_modes: int | None = None, *, check: bool = True, return_coords: bool = False):
        """Lowest modes at term coefficients ``k_coeffs`` / ``m_coeffs`` (as :meth:`Model.K` / ``M``).

        Parameters
        ----------
        k_coeffs, m_coeffs : dict
            Term name -> coefficient; missing terms are 0; ``K0`` / ``M0`` always 1.  ``m_coeffs``
            None means the reference masses ``m_ref``.
        n_modes : int, optional
            Default :attr:`n_modes`.
        check : bool
            Warn when a coefficient lies outside the verified range.
        return_coords : bool
            Also return the generalised coordinates ``y`` (r, n_modes).

        Returns
        -------
        freqs_Hz : ndarray, shape (n_modes,)
        shapes : ndarray, shape (n_labels, n_modes)
            Mass-normalised displacements at the measuring points.
        """
        n, Kr, Mr = self._reduced(k_coeffs, m_coeffs, n_modes, check)
        if Mr is None:  # LAPACK dsyevr directly: the wrapper of scipy.linalg.eigh costs ~15 % here
            w, z, m, _, info = lapack.dsyevr(Kr, range="I", il=1, iu=n)
            if info != 0 or m != n:
                raise ModelError(f"rom: dense eigen-solve failed (LAPACK info {info}) — check the coefficients")
            lam, y = w[:n], z[:, :n]
        else:
            lam, y = sla.eigh(Kr, Mr, subset_by_index=[0, n - 1], check_finite=False, driver="gvx")
        freqs = np.sqrt(np.clip(lam, 0.0, None)) / TWO_PI
        shapes = self.probe @ y
        idx = np.argmax(np.abs(shapes), axis=0)
        sign = np.sign(shapes[idx, np.arange(n)])
        sign[sign == 0] = 1.0
        shapes = shapes * sign
        if return_coords:
            return freqs, shapes, y * sign
        return freqs, shapes

    def _reduced(self, k_coeffs, m_coeffs, n_modes, check):
        """Number of modes (checked), and the reduced ``(Kr, Mr)`` at these coefficients."""
        n = self.n_modes if n_modes is None else int(n_modes)
        if not 0 < n <= self.size:
            raise ModelError(f"rom: n_modes = {n} must be between 1 and the basis size {self.size}")
        if check:
            self._check_range(k_coeffs, self.m_ref if m_coeffs is None else m_coeffs)
        return (n, *self.reduced_matrices(k_coeffs, m_coeffs))

    def frequencies(self, k_coeffs: dict[str, float], m_coeffs: dict[str, float] | None = None,
                    n_modes: int | None = None, *, check: bool = True) -> np.ndarray:
        """Frequencies only (Hz, shape ``(n_modes,)``): the same values as :meth:`solve`, about twice
        as fast (no eigenvectors; for frequency-only pairing, surfaces and sweeps)."""
        n, Kr, Mr = self._reduced(k_coeffs, m_coeffs, n_modes, check)
        if Mr is not None:  # standard form L^-1 Kr L^-T with Mr = L L^T
            L = np.linalg.cholesky(Mr)
            Kr = sla.solve_triangular(L, sla.solve_triangular(L, Kr, lower=True).T, lower=True)
        lam = np.linalg.eigvalsh(Kr)[:n]
        return np.sqrt(np.clip(lam, 0.0, None)) / TWO_PI

    def coefficients(self, theta: dict[str, float] | None = None) -> tuple[dict, dict]:
        """``(k_coeffs, m_coeffs)`` at joint parameters ``theta`` (N/m^3; missing ones at default).

        Same result as :func:`jointid.fe.model.base_coefficients` for the configuration the ROM was
        built with.
        """
        p = self.params
        values = dict(p["defaults"])
        unknown = [n for n in (theta or {}) if n not in values]
        if unknown:
            raise ModelError([f"rom: joint parameter '{n}' is unknown (known: {', '.join(values)})"
                              for n in unknown])
        values.update(theta or {})
        kc = dict(p["k_fixed"])
        for name, terms in p["terms"].items():
            for term in terms:
                kc[term] = kc.get(term, 0.0) + values[name]
        return kc, dict(p["m"])

    def solve_theta(self, theta: dict[str, float], n_modes: int | None = None, **kw):
        """:meth:`solve` at joint parameters ``theta`` (N/m^3)."""
        kc, mc = self.coefficients(theta)
        return self.solve(kc, mc, n_modes, **kw)

    def expand(self, y: np.ndarray) -> np.ndarray:
        """Full DOF vectors ``V @ y`` (n_dofs, n) from generalised coordinates (needs the basis)."""
        if self.basis is None:
            raise ModelError("rom: the basis was not stored (saved with include_basis=False) — "
                             "rebuild the ROM or load a file saved with the basis")
        return self.basis @ y

    # ------------------------------------------------------------ persistence
    def save(self, path, include_basis: bool = True) -> None:
        """Write the ROM to one ``.npz`` file atomically (the basis only if ``include_basis``)."""
        meta = {"format": _FORMAT, "k_names": self.k_names, "m_names": self.m_names,
                "labels": list(self.labels), "n_modes": self.n_modes, "m_ref": self.m_ref,
                "coeff_range": self.coeff_range, "params": self.params, "report": self.report}
        arrays = {"k_terms": self.k_terms, "m_terms": self.m_terms, "probe": self.probe,
                  "meta": np.frombuffer(json.dumps(meta, default=_json_default).encode(), dtype=np.uint8)}
        if include_basis and self.basis is not None:
            arrays["basis"] = self.basis
        io.write_npz(path, **arrays)

    @classmethod
    def load(cls, path) -> "ROM":
        """Read a ROM written by :meth:`save`."""
        try:
            z = np.load(path, allow_pickle=False)
            meta = json.loads(bytes(z["meta"]).decode())
        except (OSError, KeyError, ValueError) as exc:
            raise ModelError(f"{path}: not a readable ROM file ({exc}) — rebuild it with build_rom") from None
        if meta.get("format") != _FORMAT:
            raise ModelError(f"{path}: format '{meta.get('format')}' is not {_FORMAT} — rebuild the ROM")
        return cls(k_names=meta["k_names"], m_names=meta["m_names"], k_terms=z["k_terms"],
                   m_terms=z["m_terms"], probe=z["probe"], labels=meta["labels"], n_modes=meta["n_modes"],
                   m_ref=meta["m_ref"], coeff_range=meta["coeff_range"], params=meta["params"],
                   report=meta["report"], basis=z["basis"] if "basis" in z.files else None)


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def load_rom(path) -> ROM:
    """Read a ROM written by :meth:`ROM.save`."""
    return ROM.load(path)


def full_modes(rom: ROM, k_coeffs: dict[str, float], m_coeffs: dict[str, float] | None = None,
               n_modes: int | None = None, *, check: bool = True) -> Modes:
    """ROM modes expanded to full DOF vectors, as :func:`jointid.fe.modal.solve_modes` returns them.

    ``phi = V y`` is mass-normalised (against ``M(m_coeffs)`` when that equals the ROM's ``m_ref``,
    which holds for every joint-parameter point of the configuration it was built for) and its sign
    is fixed as the full solver fixes it: the largest component of the whole DOF vector positive.
    Shapes at the measuring points are then ``model.probe @ phi``, comparable with a full solve
    component by component (not only by MAC).  Needs the basis (:attr:`ROM.basis`).

    Returns
    -------
    jointid.fe.modal.Modes
        ``freqs_Hz (n_modes,)`` Hz, ``phi (n_dofs, n_modes)``, zero at fixed DOFs.
    """
    freqs, _, y = rom.solve(k_coeffs, m_coeffs, n_modes, check=check, return_coords=True)
    phi = rom.expand(y)
    idx = np.argmax(np.abs(phi), axis=0)
    sign = np.sign(phi[idx, np.arange(phi.shape[1])])
    sign[sign == 0] = 1.0
    return Modes(freqs_Hz=freqs, phi=phi * sign)


# ------------------------------------------------------------------ building
def frequency_error(f_rom: np.ndarray, f_full: np.ndarray, min_freq_Hz: float = 0.0) -> np.ndarray:
    """Relative error ``|f_rom - f_full| / f_full`` mode by mode (NaN below ``min_freq_Hz``)."""
    f_rom, f_full = np.asarray(f_rom, float), np.asarray(f_full, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(f_rom - f_full) / f_full
    return np.where(f_full >= max(min_freq_Hz, 1e-300), err, np.nan)


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


def _full_solve(model, kc, mc, n, solver):
    return solve_model(model, kc, mc, n, shift_Hz=solver.get("shift_Hz", -10.0),
                       backend=solver.get("backend", "auto"))


def _inverse_iterates(b: "_Builder", model, kc, mc, n, solver, n_inverse: int, labels) -> int:
    """Improve the current ROM's ``n`` lowest Ritz vectors at ``(kc, mc)`` by ``n_inverse`` block
    inverse iterations with the full ``K - sigma M`` (one factorisation); add them to the basis.
    Returns the number of basis vectors added."""
    shift = float(solver.get("shift_Hz", -10.0))
    sigma = -abs(TWO_PI * shift) ** 2 if shift <= 0 else (TWO_PI * shift) ** 2
    free = free_dofs(model.n_dofs, model.fixed)
    K, M = model.K(kc), model.M(mc)
    A = restrict(K - sigma * M, free)
    try:
        fac = factorize(A, solver.get("backend", "auto"), model.ordering)
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


def build_rom(model, cfg: dict, n_modes: int | None = None, points="corners", *, n_extra: int = 2,
              training: str = "inverse", n_inverse: int = 1, tol: float = 1e-4, n_verify: int = 2, max_rounds: int = 6, n_candidates: int = 32,
              seed: int = 0, extra_points: list[tuple[dict, dict]] | None = None, rank_rtol: float = 1e-6,
              keep_basis: bool = True, labels: list[str] | None = None, candidates=None, progress=None) -> ROM:
    """Build and verify a parametric ROM of ``model`` over the joint-parameter box of ``cfg``.

    Greedy error control: ``n_candidates`` random interior points of the coded box are ranked by
    :func:`residual_indicator`; in each round the ``n_verify`` worst ones are solved in full and the
    true relative frequency errors of the tracked modes are measured.  If one exceeds ``tol``, the
    full modes of the failing points join the basis and the next round starts; otherwise the ROM is
    verified.

    Parameters
    ----------
    model : jointid.fe.fem.Model
        The assembled affine model (``model.build_model`` or ``model.load_model``).
    cfg : dict
        Validated configuration (``joints``, ``rig``, ``solver`` sections are used).
    n_modes : int, optional
        Tracked modes (default ``solver.n_modes``); the ROM returns this many by default.
    points : ``"corners"``, ``"star"``, array (n, p) or list of dict
        Training points: coded points in ``[-1, 1]^p`` over ``joints.parameters`` (log coding as in
        :mod:`jointid.identification.doe`) or dicts of joint parameters in N/m^3 (e.g. an identified optimum).
    training : ``"inverse"`` or ``"modes"``
        How training points after the first enter the basis: block inverse iterations from the current
        Ritz vectors (``"inverse"``, default, ``n_inverse`` steps, one factorisation each) or the
        modes of a full solve (``"modes"``).  The first point is always a full solve.
    n_inverse : int
        Inverse-iteration steps per training point (``training="inverse"``).
    n_extra : int
        Modes computed beyond ``n_modes`` at each training point (default 2: a small basis evaluates
        fast, and the greedy error control adds what is missing).
    tol : float
        Target relative frequency error on the tracked modes (modes at or above
        ``solver.min_freq_Hz``).
    n_verify, max_rounds, n_candidates, seed : int
        Full verification solves per round, the most rounds, the size and seed of the candidate set.
        ``n_verify = 0`` skips the error control.
    extra_points : list of (k_coeffs, m_coeffs), optional
        Further training points given directly as term coefficients (e.g. effect terms).
    rank_rtol : float
        Relative Gram eigenvalue below which a training direction is dropped (basis compression);
        enrichment uses ``min(rank_rtol, 1e-10)``.
    keep_basis : bool
        Keep the (n_dofs x r) basis in the ROM (for :meth:`ROM.expand` and the indicator).
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
    say = progress or (lambda msg: None)
    solver = cfg.get("solver", {})
    n_modes = int(n_modes or solver.get("n_modes", 12))
    n_extra = int(n_extra)
    min_f = float(solver.get("min_freq_Hz", 0.0))
    jcfg = cfg["joints"]
    names = list(jcfg["parameters"])
    lower = np.array([jcfg["parameters"][n]["lower"] for n in names], float)
    upper = np.array([jcfg["parameters"][n]["upper"] for n in names], float)

    def coeffs_coded(x):
        theta = dict(zip(names, to_physical(np.atleast_2d(x), lower, upper)[0].tolist()))
        return theta, base_coefficients(cfg, model, theta)

    train: list[tuple[dict, tuple[dict, dict]]] = []
    pts = training_points(len(names), points) if isinstance(points, str) else points
    for pt in pts:
        if isinstance(pt, dict):
            train.append((dict(pt), base_coefficients(cfg, model, dict(pt))))
        else:
            x = np.asarray(pt, float)
            if x.shape != (len(names),):
                raise ModelError(f"rom: training point {x.tolist()} has {x.size} coordinates; "
                                 f"the box has {len(names)} parameters ({', '.join(names)})")
            train.append(coeffs_coded(x))
    for kc, mc in extra_points or []:
        train.append(({}, (dict(kc), dict(mc))))
    if not train:
        raise ModelError("rom: no training points — give points='corners' or a list of points")

    b = _Builder(model, train[0][1][1], rank_rtol)
    covered: dict[str, list[float]] = {}

    def cover(kc, mc):
        for nme, c in list(kc.items()) + list(mc.items()):
            lo, hi = covered.get(nme, [c, c])
            covered[nme] = [min(lo, c), max(hi, c)]

    if training not in ("inverse", "modes"):
        raise ModelError(f"rom: training '{training}' is unknown — use inverse or modes")
    n_train = n_modes + n_extra
    report = {"n_modes": n_modes, "n_train_modes": n_train, "tol": tol, "training_kind": training,
              "training": [], "rounds": []}
    for k, (theta, (kc, mc)) in enumerate(train):
        if k == 0 or training == "modes":
            added, how = b.add(_full_solve(model, kc, mc, n_train, solver).phi), "full solve"
        else:
            added = _inverse_iterates(b, model, kc, mc, n_train, solver, n_inverse, labels)
            how = f"{max(1, int(n_inverse))} inverse iteration(s)"
        cover(kc, mc)
        report["training"].append({"theta": theta, "added": added, "how": how})
        say(f"rom: training point {k + 1}/{len(train)} ({how}): +{added} vectors (r = {b.V.shape[1]})")

    rng = np.random.default_rng(seed)
    coded = rng.uniform(-1.0, 1.0, size=(n_candidates, len(names)))
    if candidates is not None:
        extra = np.atleast_2d(np.asarray(candidates, float))
        if extra.size and extra.shape[1] != len(names):
            raise ModelError(f"rom: candidate points have {extra.shape[1]} coordinates; the box has "
                             f"{len(names)} parameters ({', '.join(names)})")
        coded = np.vstack([coded, extra]) if extra.size else coded
    candidates = [coeffs_coded(x) for x in coded]
    for theta, (kc, mc) in candidates:
        cover(kc, mc)  # the greedy search certifies the box spanned by the candidates
    verified = n_verify <= 0
    max_err = float("nan")
    b.rank_rtol = min(rank_rtol, 1e-10)
    for rnd in range(max_rounds if n_verify > 0 else 0):
        rom = _assemble(b, model, n_modes, covered, labels)
        if not candidates:
            break
        eta = np.array([residual_indicator(model, rom, kc, mc, V=b.V).max() for _, (kc, mc) in candidates])
        worst = np.argsort(-eta)[:n_verify]
        checked, failing = [], []
        for i in worst:
            theta, (kc, mc) = candidates[i]
            modes = _full_solve(model, kc, mc, n_train, solver)
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
        say(f"rom: round {rnd}: r = {rom.size}, worst indicator {eta.max():.1e}, max relative frequency "
            f"error at the {len(checked)} worst candidates {max_err:.2e}")
        report["rounds"].append(info)
        if not failing:
            verified = True
            break
        info["added"] = sum(b.add(m.phi) for m in failing)
        if info["added"] == 0:
            break
    rom = _assemble(b, model, n_modes, covered, labels, keep_basis=keep_basis)
    report.update({"size": rom.size, "max_error": max_err, "verified": bool(verified)})
    rom.report = report
    rom.params = _param_map(cfg, model, names, lower, upper)
    if not verified:
        warnings.warn(f"rom: relative frequency error {max_err:.2e} still above tol = {tol:.1e} after "
                      f"{len(report['rounds'])} enrichment rounds (r = {rom.size}) — raise max_rounds, "
                      "n_extra or n_candidates, or narrow the parameter bounds", NumericalWarning, stacklevel=2)
    return rom


def _assemble(b: _Builder, model, n_modes, covered, labels, keep_basis=False) -> ROM:
    if labels is None:
        from jointid.geometry.points import dof_labels
        import pandas as pd

        labels = dof_labels(pd.DataFrame(model.meta["points"])) if "points" in model.meta else \
            [f"p{i}" for i in range(model.probe.shape[0])]
    return ROM(k_names=list(b.k_names), m_names=list(b.m_names), k_terms=b.k_terms.copy(),
               m_terms=b.m_terms.copy(), probe=np.asarray(model.probe @ b.V), labels=list(labels),
               n_modes=n_modes, m_ref=dict(b.m_ref), coeff_range={k: list(v) for k, v in covered.items()},
               basis=b.V.copy() if keep_basis else None)


def _param_map(cfg, model, names, lower, upper) -> dict:
    jcfg = cfg["joints"]
    terms = joint_terms(jcfg)
    kc, mc = base_coefficients(cfg, model, None)
    defaults = {n: float(np.sqrt(s["lower"] * s["upper"])) for n, s in jcfg["parameters"].items()}
    defaults.update({k: float(v) for k, v in jcfg.get("fixed", {}).items()})
    k_fixed = dict(kc)
    for name, ts in terms.items():
        for t in ts:
            k_fixed[t] = k_fixed.get(t, 0.0) - defaults.get(name, 0.0)
    k_fixed = {k: v for k, v in k_fixed.items() if abs(v) > 1e-12 * max(1.0, abs(kc.get(k, 0.0)))}
    return {"terms": terms, "defaults": defaults, "k_fixed": k_fixed, "m": mc, "names": names,
            "lower": lower.tolist(), "upper": upper.tolist()}
