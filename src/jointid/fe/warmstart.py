"""A reduced solver's subspace kept from one run to the next on the same model (``diagnosis.reuse_subspace``).

A diagnosis ends with a basis that spans every point it visited: the baseline, each candidate and
each pair it refitted.  :func:`save` writes it beside the outputs (``subspace.npz``); the next run on
the same model (:func:`fingerprint` of its matrices) starts its reduced solver from it (:func:`load`)
instead of from the exact modes and first-order responses at the reference point, and enriches it
only where the new questions lead elsewhere.  That is the loop of docs/effects.md: enable the effect
the last run suggested, rerun, and most of the subspace the answer needs is already there.

Every answer is certified as before (each point's full-space residual check at the solver
tolerance, a Sturm count at the reported optima), so a warm run agrees with a run from scratch to
that tolerance (1e-6 relative in each eigenvalue), not bit for bit.  A run from clean has no file
to start from, so it stays bit-reproducible; ``diagnosis.reuse_subspace: false`` makes every run so.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

MAX_SAVED = 600
"""Most basis vectors kept (the first ones; beyond it a solver would soon restart anyway)."""


def fingerprint(system) -> str:
    """Short hash of a model's terms (names, sizes, a stride of their entries) and fixed DOFs."""
    h = hashlib.sha256(f"{system.n_dofs}".encode())
    h.update(np.ascontiguousarray(system.fixed, dtype=np.int64).tobytes())
    for group in (system.stiffness, system.mass):
        for name in sorted(group):
            A = group[name].tocsr()
            step = max(1, A.nnz // 4096)
            h.update(name.encode())
            h.update(np.array([A.nnz, *A.shape], dtype=np.int64).tobytes())
            h.update(np.ascontiguousarray(A.data[::step], dtype=np.float64).tobytes())
            h.update(np.ascontiguousarray(A.indices[::step], dtype=np.int64).tobytes())
    return h.hexdigest()[:20]


def save(path: str | Path, V: np.ndarray, system) -> None:
    """Write the first :data:`MAX_SAVED` columns of ``V`` (free DOFs) with the model's fingerprint;
    written to a temporary file and renamed, so a reader never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
    try:
        np.savez(tmp, V=np.ascontiguousarray(V[:, :MAX_SAVED]), fingerprint=np.array(fingerprint(system)))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load(path: str | Path, system, n_free: int) -> tuple[np.ndarray | None, str]:
    """The kept basis of ``system`` at ``path`` and a line saying what was found: ``(None, why)`` when
    there is none, it belongs to another model or it cannot be read."""
    path = Path(path)
    if not path.exists():
        return None, "no subspace kept from an earlier run: starting afresh"
    try:
        with np.load(path) as f:
            if str(f["fingerprint"]) != fingerprint(system):
                return None, f"{path}: kept for another model: starting afresh"
            V = np.array(f["V"])
    except (OSError, ValueError, KeyError) as exc:
        return None, f"{path}: unreadable ({exc}): starting afresh"
    if V.ndim != 2 or V.shape[0] != n_free or not np.isfinite(V).all():
        return None, f"{path}: not a basis of this model's {n_free} free DOFs: starting afresh"
    return V, f"starting from the {V.shape[1]} vectors kept from the last run ({path})"
