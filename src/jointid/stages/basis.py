"""Rule ``diagnosis_basis``: one reduced basis of the run's model, built once, that the diagnosis and
every hypothesis on the run's model start from (``results/model/diagnosis_basis.npz``).

Each of those jobs used to build the same reduced solver itself: the exact modes of the baseline at
its start and their first-order responses to every model term (about 11 s on the default mesh).
This rule builds it once, as the diagnosis would at its first step, and keeps it with
:func:`jointid.fe.warmstart.save`.  A job that starts from it enriches it where its own questions
lead, and every answer is still certified in the full space (a residual check at each point, a
Sturm count at each reported optimum), so the answers are the same to the solver tolerance (1e-6
relative in each eigenvalue).  A hypothesis with another material of a part has the run's terms plus
that part's solid terms: it projects those on the basis and goes on from it.  A job whose model differs
(another geometry, a changed term: :func:`jointid.fe.warmstart.fingerprint`) starts afresh and says so.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from jointid.data.dataset import read_dataset
from jointid.diagnosis.fitting import Diagnoser, print_log
from jointid.diagnosis.terms import build_system
from jointid.diagnosis.variants import Variant, dataset_states
from jointid.fe import warmstart
from jointid.fe.model import load_model
from jointid.fe.modal import free_dofs
from jointid.threads import limit_threads

if TYPE_CHECKING:
    from jointid.config.typed_diagnosis import DiagnosisSettings


def measured_states(settings: DiagnosisSettings, system) -> list:
    """:class:`~jointid.diagnosis.variants.StateData` of every configured state, read from its dataset
    folder (``settings.datasets``; states sharing a folder are read together)."""
    folders: dict[str, list[str]] = {}
    for state, folder in settings.datasets.items():
        folders.setdefault(folder, []).append(state)
    data = []
    for folder, states in folders.items():
        ds = read_dataset(folder, measuring_points=system.meta["points"])
        data += dataset_states(ds, system, settings, states)
    return data


def run_basis(settings: DiagnosisSettings, matrices: str, out_npz: str, *, log=print_log) -> None:
    """Build the reduced solver of the run's model at the diagnosis's first point (the baseline at its
    start, the run's measured states) and keep its basis in ``out_npz``."""
    limit_threads(1)
    t0 = time.time()
    system = build_system(load_model(matrices), settings.model)
    diag = Diagnoser(system, settings, measured_states(settings, system), log=log)
    base = Variant(system, settings, [])
    diag.ensure_solver(base, base.x_start())
    # without its products (each reader forms them, about 0.5 s): 39 MB on the default mesh.  (A
    # single-precision start that each reader projects itself took 20 MB, for about 1 s more per reader.)
    warmstart.save(out_npz, diag.solver, system, products=())
    log(f"diagnosis basis: {diag.solver.V.shape[1]} vectors of {system.n_dofs} DOFs kept in {out_npz} "
        f"({time.time() - t0:.1f} s)")


def load_basis(path: str | None, system, log=print_log):
    """The basis at ``path`` for ``system`` (:class:`jointid.fe.warmstart.Kept`), or None with a line
    saying why (no file given, another model)."""
    if not path:
        return None
    kept, why = warmstart.load(path, system, len(free_dofs(system.n_dofs, system.fixed)))
    log(f"diagnosis basis: {why.replace('kept from the last run', 'of the shared basis')}")
    return kept
