"""Designs of experiments (DOE) for response-surface model updating.

All designs live in *coded* variables ``x`` in ``[-1, 1]`` per factor.  A coded value maps to a
physical parameter ``theta`` (e.g. ``k_normal_N_per_m3``) log-uniformly between its bounds::

    log10(theta) = log10(lower) + (x + 1) / 2 * (log10(upper) - log10(lower))

so ``x = -1`` is the lower bound, ``x = +1`` the upper bound and ``x = 0`` the geometric mean.
Joint stiffnesses span decades and the frequencies depend on them roughly as a power law, which is
why the coding is logarithmic (Ren & Chen, Eng. Struct. 2010, use coded variables likewise).

Designs
-------
* ``"ccf"``: face-centred central composite design: the ``2**k`` factorial corners, ``2k`` axial
  points at ``+-1`` and ``n_center`` centre points; ``2**k + 2k + n_center`` runs, three levels per
  factor, supports a full quadratic for any ``k``.
* ``"box_behnken"``: for every pair of factors the four ``(+-1, +-1)`` combinations with the other
  factors at 0, plus ``n_center`` centre points (``2k(k-1) + n_center`` runs; the classical BBD for
  ``k = 3, 4, 5``; for ``k >= 6`` this pairwise construction is larger than the tabulated
  incomplete-block designs but still a valid three-level design).  Needs ``k >= 3``.
* ``"lhs"``: a Latin hypercube (``scipy.stats.qmc.LatinHypercube``) of ``n_samples`` rows scaled to
  ``[-1, 1]``, followed by one centre point.

Rule of thumb: use at least 2-3 times as many runs as the quadratic has terms
(:func:`n_quadratic_terms`).
"""

from __future__ import annotations

import itertools

import numpy as np

from jointid.errors import ConfigError

__all__ = [
    "KINDS",
    "design",
    "n_quadratic_terms",
    "check_design_size",
    "to_physical",
    "to_coded",
    "verification_points",
    "latin_hypercube",
    "check_bounds",
]

KINDS = ("ccf", "box_behnken", "lhs")

# Fixed offset that gives verification points a random stream independent of the design's.
_VERIFICATION_STREAM = 0x7E51F1


def latin_hypercube(n: int, d: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` LHS points in ``[0, 1)^d`` drawn from ``rng``: in each dimension one point per stratum
    ``[(k - 1)/n, k/n)``, the strata shuffled per dimension, the point uniform inside its stratum.

    The draws are those of SciPy's ``qmc.LatinHypercube(d, rng=rng).random(n)`` (SciPy >= 1.15;
    strength 1, no optimisation: a child generator spawned from ``rng``), bit for bit
    (``tests/test_doe.py``), without importing ``scipy.stats`` (about 0.4 s, paid by every Snakemake
    start: the Snakefile builds the DOE sheet).
    """
    rng = rng.spawn(1)[0]
    samples = rng.uniform(size=(n, d))
    perms = np.tile(np.arange(1, n + 1), (d, 1))
    for i in range(d):
        rng.shuffle(perms[i, :])
    return (perms.T - samples) / n


def n_quadratic_terms(k: int) -> int:
    """Number of coefficients of a full quadratic in ``k`` factors: ``(k + 1)(k + 2) / 2``."""
    k = int(k)
    return (k + 1) * (k + 2) // 2


def check_design_size(n_points: int, k: int) -> None:
    """Raise :class:`ConfigError` if ``n_points`` runs cannot fit a full quadratic in ``k`` factors.

    Parameters
    ----------
    n_points : int
        Number of DOE runs (distinct or not).
    k : int
        Number of factors.
    """
    m = n_quadratic_terms(k)
    if n_points < m:
        raise ConfigError(
            f"doe: DOE has {n_points} points but a full quadratic in {k} factors needs {m}; "
            f"use ccf or raise doe.n_samples to >= {2 * m}"
        )


def design(kind: str, n_factors: int, *, n_center: int = 1, n_samples: int = 0,
           seed: int = 0) -> np.ndarray:
    """Build a design in coded units.

    Parameters
    ----------
    kind : {"ccf", "box_behnken", "lhs"}
        Design family (see module docstring).
    n_factors : int
        Number of factors ``k >= 1``.
    n_center : int, optional
        Centre points appended to ``ccf`` and ``box_behnken`` designs (``>= 0``).  For ``lhs`` the
        centre is always added exactly once.
    n_samples : int, optional
        Number of LHS rows (``lhs`` only, ``>= 1``).
    seed : int, optional
        Seed of the LHS stream (``lhs`` only).

    Returns
    -------
    numpy.ndarray, shape (n_points, n_factors)
        Coded design points in ``[-1, 1]``, in a deterministic order.

    Raises
    ------
    ConfigError
        Unknown kind, ``k < 1``, Box-Behnken with ``k < 3``, ``lhs`` without ``n_samples``.
    """
    k = int(n_factors)
    problems = []
    if kind not in KINDS:
        problems.append(f"doe.kind: unknown design {kind!r}; use one of {', '.join(KINDS)}")
    if k < 1:
        problems.append(f"doe: n_factors = {k}; at least one joint parameter must be identified")
    if n_center < 0:
        problems.append(f"doe.n_center = {n_center} is negative; use 0 or more centre points")
    if kind == "box_behnken" and 1 <= k < 3:
        problems.append(
            f"doe.kind: box_behnken needs at least 3 factors but there are {k}; use kind: ccf "
            f"(for 2 factors the face-centred CCD is the standard three-level design)"
        )
    if kind == "lhs" and n_samples < 1:
        problems.append(
            f"doe.n_samples = {n_samples}; an lhs design needs n_samples >= 1 "
            f"(recommended >= {2 * n_quadratic_terms(max(k, 1))} for a quadratic surface)"
        )
    if problems:
        raise ConfigError(problems)

    if kind == "ccf":
        corners = np.array(list(itertools.product((-1.0, 1.0), repeat=k)))
        axial = np.zeros((2 * k, k))
        for i in range(k):
            axial[2 * i, i] = -1.0
            axial[2 * i + 1, i] = 1.0
        pts = np.vstack([corners, axial, np.zeros((n_center, k))])
    elif kind == "box_behnken":
        rows = []
        for i, j in itertools.combinations(range(k), 2):
            for a, b in itertools.product((-1.0, 1.0), repeat=2):
                row = np.zeros(k)
                row[i], row[j] = a, b
                rows.append(row)
        pts = np.vstack([np.array(rows), np.zeros((n_center, k))])
    else:  # lhs
        u = latin_hypercube(int(n_samples), k, np.random.default_rng(seed))
        pts = np.vstack([2.0 * u - 1.0, np.zeros((1, k))])
    return pts.astype(float)


def check_bounds(lower, upper, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Physical ``(lower, upper)`` bounds as float arrays (k,) (or one pair); raise one
    :class:`ConfigError` unless each pair is finite, positive (log coding) and increasing."""
    lo = np.atleast_1d(np.asarray(lower, dtype=float))
    hi = np.atleast_1d(np.asarray(upper, dtype=float))
    problems = []
    if lo.shape != hi.shape:
        problems.append(f"bounds: lower has {lo.size} entries but upper has {hi.size}; give one "
                        f"(lower, upper) pair per parameter")
    else:
        if k is not None and lo.size not in (1, k):
            problems.append(f"bounds: {lo.size} (lower, upper) pairs for {k} parameters; give one "
                            f"pair per parameter")
        for i, (a, b) in enumerate(zip(lo, hi)):
            if not (np.isfinite(a) and np.isfinite(b) and a > 0 and b > 0):
                problems.append(f"bounds[{i}]: ({a:g}, {b:g}) must be finite and > 0 for a "
                                f"log-scaled parameter")
            elif not b > a:
                problems.append(f"bounds[{i}]: upper {b:g} must be greater than lower {a:g}")
    if problems:
        raise ConfigError(problems)
    return lo, hi


def to_physical(x, lower, upper) -> np.ndarray:
    """Map coded values to physical values (log-uniform).

    Parameters
    ----------
    x : array_like, shape (k,) or (n, k)
        Coded values; values outside ``[-1, 1]`` extrapolate log-linearly.
    lower, upper : array_like, shape (k,)
        Physical bounds (same unit as the parameter, > 0), ``upper > lower``.

    Returns
    -------
    numpy.ndarray
        Physical values, same shape as ``x``.
    """
    x = np.asarray(x, dtype=float)
    lo, hi = check_bounds(lower, upper, x.shape[-1] if x.ndim else None)
    a, b = np.log10(lo), np.log10(hi)
    return 10.0 ** (a + (x + 1.0) / 2.0 * (b - a))


def to_coded(theta, lower, upper) -> np.ndarray:
    """Inverse of :func:`to_physical`.

    Parameters
    ----------
    theta : array_like, shape (k,) or (n, k)
        Physical values (> 0).
    lower, upper : array_like, shape (k,)
        Physical bounds.

    Returns
    -------
    numpy.ndarray
        Coded values, same shape as ``theta`` (``-1`` at ``lower``, ``+1`` at ``upper``).
    """
    theta = np.asarray(theta, dtype=float)
    lo, hi = check_bounds(lower, upper, theta.shape[-1] if theta.ndim else None)
    if np.any(~(theta > 0)):
        raise ConfigError("to_coded: parameter values must be > 0 (they are coded on a log10 scale)")
    a, b = np.log10(lo), np.log10(hi)
    return 2.0 * (np.log10(theta) - a) / (b - a) - 1.0


def verification_points(n: int, n_factors: int, seed: int = 0) -> np.ndarray:
    """Fresh interior points for checking a fitted surface against the FE model.

    A Latin hypercube drawn from a random stream independent of :func:`design`'s (for the same
    ``seed``), scaled to ``[-0.9, 0.9]`` so the check stays inside the DOE region.

    Parameters
    ----------
    n : int
        Number of points (``>= 1``).
    n_factors : int
        Number of factors.
    seed : int, optional
        Seed.

    Returns
    -------
    numpy.ndarray, shape (n, n_factors)
    """
    if n < 1 or n_factors < 1:
        raise ConfigError(f"verification_points: n = {n} and n_factors = {n_factors} must be >= 1")
    rng = np.random.default_rng([int(seed), _VERIFICATION_STREAM])
    return 0.9 * (2.0 * latin_hypercube(int(n), int(n_factors), rng) - 1.0)
