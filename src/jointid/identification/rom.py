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
    (:func:`jointid.identification.rom_build.residual_indicator`, no factorisation); the worst few
    are solved in full and compared with the ROM.  While the relative frequency error of a tracked
    mode (the lowest ``n_modes`` at or above ``min_freq_Hz``) exceeds ``tol`` (default 1e-4), the
    full modes of the failing points are added to the basis and the next round ranks the remaining
    candidates again.  The history is kept in :attr:`ROM.report`.
Accuracy
    Rayleigh-Ritz frequencies are upper bounds of the full ones, mode by mode.  The ROM is verified
    inside the coefficient ranges it was trained and checked on (:attr:`ROM.coeff_range`); outside
    them :meth:`ROM.solve` warns (:class:`jointid.errors.NumericalWarning`).
Building
    :func:`jointid.identification.rom_build.build_rom` (training, basis, error control); this module
    holds the model itself, its evaluation and its file.
Speed
    One evaluation costs one dense r x r eigen-solve (~1 ms at r = 100 with single-threaded BLAS;
    set ``OPENBLAS_NUM_THREADS=1`` when running many small evaluations on a shared machine).

Shapes at the measuring points are ``probe @ V @ y`` (rows ``<point>:<direction>`` as
``model.probe``), mass-normalised; the sign is fixed so that the largest component *at the measuring
points* is positive (the full solver fixes it on the whole DOF vector, so compare shapes by MAC).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from jointid import io
from jointid.errors import ModelError, NumericalWarning
from jointid.fe.modal import TWO_PI, Modes, fix_signs

__all__ = ["ROM", "load_rom", "full_modes", "frequency_error"]

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
        matrices = self.reduced_matrices(k_coeffs, m_coeffs)  # an unknown term raises here, before the range check
        if check:
            self._check_range(k_coeffs, self.m_ref if m_coeffs is None else m_coeffs)
        return (n, *matrices)

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
    return Modes(freqs_Hz=freqs, phi=fix_signs(rom.expand(y)))


def frequency_error(f_rom: np.ndarray, f_full: np.ndarray, min_freq_Hz: float = 0.0) -> np.ndarray:
    """Relative error ``|f_rom - f_full| / f_full`` mode by mode (NaN below ``min_freq_Hz``)."""
    f_rom, f_full = np.asarray(f_rom, float), np.asarray(f_full, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(f_rom - f_full) / f_full
    return np.where(f_full >= max(min_freq_Hz, 1e-300), err, np.nan)
