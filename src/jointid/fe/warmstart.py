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

The diagnosis keeps the basis in a file of its own beside ``subspace.npz`` (``apart``: ``subspace.basis-<digest>.npy``,
named in it).  A rerun whose basis did not grow (the loop's usual case: its new points pass their checks on the
kept columns) then rewrites only the small file with its records, not the 210 MB of the paper's 448 vectors
(about 0.6 s of the loop); the shared basis of the workflow (rule ``diagnosis_basis``) stays one file.

The file keeps the basis, not its products with the model's matrices (``K0 V``, ``M0 V``). Kept in
single precision as the solver holds them, they would add half the basis's size again (about 105 MB
of ``results/`` for the paper's 448 vectors; ``results/`` is held to 500 MB, issue 54).  A run that
adopts the basis forms them again (about 2.4 s for ``K0 V`` and 0.9 s for ``M0 V`` on the default
mesh), or, a diagnosis rerun with records of its fits, defers them: its first checks multiply by the
sparse terms, and it forms the products only when its checks become many
(:data:`jointid.fe.reduced.CHECKS_BEFORE_PRODUCTS`).  It also keeps what the
run learnt at single points of the model: its Sturm counts (a count is the model's, at those
coefficients, whatever the subspace), the points whose full-space check passed
on the kept columns (still passed on the same columns: a run that asks them again, or certifies an
optimum there, checks nothing there) and the records of its fits
(:class:`jointid.diagnosis.memo.FitMemo`: a fit asked again with exactly the same inputs starts at
its recorded optimum and is checked there, unless a kept check already passed there).
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

MAX_SAVED = 600
"""Most basis vectors kept (the first ones; beyond it a solver would soon restart anyway)."""


def fingerprint(system) -> dict[str, str]:
    """Short hashes of a model: ``"#dofs"`` of its size and fixed DOFs, and one per term (its name,
    size and a stride of its entries).  A basis kept for one model serves another that has the same
    size, fixed DOFs and terms plus more (:func:`load`)."""
    h = hashlib.sha256(f"{system.n_dofs}".encode())
    h.update(np.ascontiguousarray(system.fixed, dtype=np.int64).tobytes())
    out = {"#dofs": h.hexdigest()[:20]}
    for group in (system.stiffness, system.mass):
        for name in sorted(group):
            A = group[name].tocsr()
            step = max(1, A.nnz // 4096)
            h = hashlib.sha256(name.encode())
            h.update(np.array([A.nnz, *A.shape], dtype=np.int64).tobytes())
            h.update(np.ascontiguousarray(A.data[::step], dtype=np.float64).tobytes())
            h.update(np.ascontiguousarray(A.indices[::step], dtype=np.int64).tobytes())
            out[name] = h.hexdigest()[:20]
    return out


@dataclass
class Kept:
    """A basis kept by an earlier run: ``V (n_free, r)`` (M-orthonormal at the reference mass
    coefficients ``mc_ref``) and the reduced matrices of every term, ``Kr``/``Mr`` (by term name).
    A :class:`jointid.fe.reduced.ReducedSolver` started from it takes ``V`` over (sets it to None)."""

    V: np.ndarray
    Kr: dict
    Mr: dict
    mc_ref: dict
    sturm: dict = field(default_factory=dict)
    """Sturm counts made at points of this model (:attr:`jointid.fe.reduced.ReducedSolver.sturm_counts`)."""
    fits: dict = field(default_factory=dict)
    """Records of the fits made on this model (:class:`jointid.diagnosis.memo.FitMemo`)."""
    certified: dict = field(default_factory=dict)
    """Points whose full-space check passed on the first ``r`` columns of ``V``: ``"<point key>#<n>"``
    -> ``(r, estimated error)`` (see :func:`certified_entries`)."""
    source: str = ""
    """The basis file ``V`` was read from (``apart``), or "" (inside the file)."""
    KV: np.ndarray | None = None
    """``K0 V`` in the basis's storage precision (:data:`jointid.fe.basis.PRODUCT_DTYPE`), or None
    (formed again); ``MV`` the same for ``M0 V``: each spares the solver a large sparse product."""
    MV: np.ndarray | None = None

    def certified_at(self, generation: int) -> dict:
        """The kept certificates as :class:`jointid.fe.reduced.ReducedSolver` keys of ``generation``.
        A check passed on the first ``r`` columns holds on any basis that contains them: a Ritz value
        on a larger subspace lies between the earlier one and the exact eigenvalue (Poincaré)."""
        out = {}
        for key, (r, worst) in self.certified.items():
            point, n = key.rsplit("#", 1)
            kc, mc = (tuple(sorted((k, float.fromhex(v)) for k, v in (e.split("=") for e in part.split(";") if e)))
                      for part in point.split("|"))
            out[(kc, mc, int(n), generation)] = (int(r), float(worst))
        return out


def save(path: str | Path, solver, system, fits: dict | None = None, products: tuple[str, ...] = (), *,
         apart: bool = False) -> None:
    # many parameters: the file, what it keeps (solver, model, fit records, products) and where the basis goes
    """Keep the first :data:`MAX_SAVED` columns of ``solver``'s basis with their reduced matrices, its
    Sturm counts, the records of the fits made (``fits``) and the model's fingerprint; written to a
    temporary file and renamed, so a reader never sees half a file.  ``products``: which of the
    solver's products with the basis to keep (``"KV"``: ``K0 V``, ``"MV"``: ``M0 V``; a reader forms
    the others; default: none, see the module doc).  ``apart``: the basis in a file of its own, written
    only when it is not the one the solver started from (module doc)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    r = min(solver.V.shape[1], MAX_SAVED)
    arrays = {"terms": np.array(json.dumps(fingerprint(system), sort_keys=True)),
              "mc_ref": np.array(json.dumps(solver.mc_ref, sort_keys=True)),
              "sturm": np.array(json.dumps(solver.sturm_counts, sort_keys=True)),
              "fits": np.array(json.dumps(fits or {})),
              "certified": np.array(json.dumps(certified_entries(solver, r), sort_keys=True))}
    iu = np.triu_indices(r)
    for group, red in (("K", solver.Kr), ("M", solver.Mr)):  # symmetric: the upper triangle, row by row
        arrays.update({f"{group}r:{name}": A[:r, :r][iu] for name, A in red.items()})
    if solver.basis.KV is not None:  # the products as the solver holds them (the same bits it would form)
        held = {"KV": solver.basis.KV, "MV": solver.basis.MV}
        arrays.update({k: held[k][:, :r] for k in products})
    if apart:
        arrays["basis_file"] = np.array(_save_basis(path, solver, r))
    else:
        arrays["V"] = np.asfortranarray(solver.V[:, :r])
    _replace(path, lambda fh: np.savez(fh, **arrays))
    _drop_other_bases(path, str(arrays["basis_file"]) if apart else "", getattr(solver, "adopted", None))


def _drop_other_bases(path: Path, named: str, adopted) -> None:
    """Remove the basis files beside ``path`` that it no longer names: the one the solver started from at
    once, any other only when older than a minute (a diagnosis and its quick half run at the same time on
    one folder would otherwise remove each other's new file; the loser's next run then starts afresh)."""
    import time

    started_from = adopted[0] if adopted else ""
    for old in path.parent.glob(f"{path.stem}.basis-*.npy"):
        try:
            if old.name != named and (old.name == started_from or time.time() - old.stat().st_mtime > 60):
                old.unlink(missing_ok=True)
        except OSError:  # gone meanwhile
            pass


def _replace(path: Path, write) -> None:
    """``write(file)`` into a temporary file beside ``path``, renamed to it (:func:`jointid.io.atomic_path`)."""
    from jointid.io import atomic_path

    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        write(fh)


def _save_basis(path: Path, solver, r: int) -> str:
    """The name of the file beside ``path`` holding the first ``r`` columns of the solver's basis: the file
    it started from when those are its columns (not grown, not restarted), else a new one named by a digest
    of its size and a sample of its entries (the same basis, the same name: a run from clean is repeatable)."""
    source, cols = getattr(solver, "adopted", None) or ("", -1)
    if source and cols == r == solver.V.shape[1] and solver.generation == 0 and (path.parent / source).is_file():
        return source
    V = np.asfortranarray(solver.V[:, :r])
    h = hashlib.sha256(np.array(V.shape, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(V.ravel(order="F")[:: max(1, V.size // 65536)]).tobytes())
    name = f"{path.stem}.basis-{h.hexdigest()[:16]}.npy"
    _replace(path.parent / name, lambda fh: np.save(fh, V))
    return name


def certified_entries(solver, r: int) -> dict:
    """The points ``solver`` certified on its present generation within the first ``r`` basis columns
    (those kept): ``"<point key>#<n>"`` -> ``(basis size, estimated error)``."""
    out = {}
    for (kc, mc, n, generation), (size, worst) in solver._certified.items():
        if generation == solver.generation and size <= r:
            out[f"{solver.point_key(dict(kc), dict(mc))}#{n}"] = (int(size), float(worst))
    return out


def _square(a: np.ndarray) -> np.ndarray:
    """A reduced matrix as kept: a symmetric matrix's upper triangle row by row (or, in a file of an
    earlier version, the whole matrix)."""
    if a.ndim != 1:
        return a
    r = int(round((np.sqrt(8 * a.size + 1) - 1) / 2))
    if r * (r + 1) // 2 != a.size:
        raise ValueError(f"{a.size} entries are no upper triangle of a square matrix")
    A = np.zeros((r, r))
    A[np.triu_indices(r)] = a
    return A + np.triu(A, 1).T


def load(path: str | Path, system, n_free: int) -> tuple[Kept | None, str]:
    """The basis kept for ``system`` at ``path`` and a line saying what was found: ``(None, why)`` when
    there is none, it belongs to another model or it cannot be read.

    A basis kept for a model whose terms ``system`` has too, unchanged, serves ``system`` even when it
    has more terms (a hypothesis's part of another material on the run's model): the solver projects
    those on the basis when it starts (:meth:`jointid.fe.reduced.ReducedSolver._start_from`).  The
    fit records and certificates are then left out: they were made on the other model."""
    path = Path(path)
    if not path.exists():
        return None, "no subspace kept from an earlier run: starting afresh"
    try:
        with np.load(path) as f:
            if "terms" not in f.files:
                return None, f"{path}: kept by an earlier version: starting afresh"
            kept_terms, here = json.loads(str(f["terms"])), fingerprint(system)
            if any(here.get(name) != h for name, h in kept_terms.items()):
                return None, f"{path}: kept for another model: starting afresh"
            added = sorted(set(here) - set(kept_terms))
            source = str(f["basis_file"]) if "basis_file" in f.files else ""
            V = np.load(path.parent / source) if source else f["V"]
            red = {g: {k.split(":", 1)[1]: _square(f[k]) for k in f.files if k.startswith(g + "r:")} for g in "KM"}
            extra = {k: json.loads(str(f[k])) if k in f.files and not added else {}
                     for k in ("sturm", "fits", "certified")}
            sturm = {k: [(float(a), int(c)) for a, c in v] for k, v in extra["sturm"].items()}
            kept = Kept(V, red["K"], red["M"], json.loads(str(f["mc_ref"])), sturm, extra["fits"], extra["certified"],
                        source)
            kept.KV, kept.MV = (f[k] if k in f.files and f[k].shape == V.shape else None for k in ("KV", "MV"))
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        return None, f"{path}: unreadable ({exc}): starting afresh"
    r = V.shape[1] if V.ndim == 2 else -1
    if V.ndim != 2 or V.shape[0] != n_free or not np.isfinite(V).all() or \
            any(A.shape != (r, r) for red in (kept.Kr, kept.Mr) for A in red.values()):
        return None, f"{path}: not a basis of this model's {n_free} free DOFs: starting afresh"
    more = f"; projecting the terms it was not kept with: {', '.join(added)}" if added else ""
    return kept, f"starting from the {r} vectors kept from the last run ({path}){more}"
