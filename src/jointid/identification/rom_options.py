"""How :func:`jointid.identification.rom_build.build_rom` trains and verifies the ROM (:class:`RomOptions`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RomOptions"]


@dataclass(frozen=True)
class RomOptions:
    """How :func:`build_rom` trains and verifies the ROM.

    Parameters
    ----------
    n_modes : int, optional
        Tracked modes (default ``solver.n_modes``); the ROM returns this many by default.
    n_extra : int
        Modes computed beyond ``n_modes`` at each training point (default 2: a small basis evaluates
        fast, and the greedy error control adds what is missing).
    training : ``"inverse"`` or ``"modes"``
        How training points after the first enter the basis: block inverse iterations from the current
        Ritz vectors (``"inverse"``, default, ``n_inverse`` steps, one factorisation each) or the
        modes of a full solve (``"modes"``).  The first point is always a full solve.
    n_inverse : int
        Inverse-iteration steps per training point (``training="inverse"``).
    tol : float
        Target relative frequency error on the tracked modes (modes at or above
        ``solver.min_freq_Hz``), dimensionless.
    n_verify, max_rounds, n_candidates, seed : int
        Full verification solves per round, the most rounds, the size and seed of the candidate set.
        ``n_verify = 0`` skips the error control.
    rank_rtol : float
        Relative Gram eigenvalue below which a training direction is dropped (basis compression);
        enrichment uses ``min(rank_rtol, 1e-10)``.
    keep_basis : bool
        Keep the (n_dofs x r) basis in the ROM (for :meth:`ROM.expand` and the indicator).
    """

    n_modes: int | None = None
    n_extra: int = 2
    training: str = "inverse"
    n_inverse: int = 1
    tol: float = 1e-4
    n_verify: int = 2
    max_rounds: int = 6
    n_candidates: int = 32
    seed: int = 0
    rank_rtol: float = 1e-6
    keep_basis: bool = True
