"""Workflow stage of the diagnosis: read a dataset and the model, diagnose, write the results.

Called by ``workflow/scripts/diagnose.py`` (rule ``diagnose``) and by the command line
``python -m jointid.diagnosis``; see docs/effects.md.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from pathlib import Path

from typing import TYPE_CHECKING

from jointid import io, isolate
from jointid.data.dataset import read_dataset
from jointid.diagnosis.fitting import print_log
from jointid.reporting.diagnosis_history import append_history, history_row
from jointid.diagnosis.loop import Diagnosis, diagnose
from jointid.diagnosis.memo import FitMemo
from jointid.errors import ModelError
from jointid.reporting.diagnosis_outputs import write_outputs
from jointid.reporting.diagnosis_figures import PRELOAD, FigureData, figures
from jointid.diagnosis.terms import build_system
from jointid.diagnosis.variants import dataset_states
from jointid.fe import warmstart
from jointid.fe.model import load_model
from jointid.fe.modal import free_dofs
from jointid.stages.basis import load_basis
from jointid.threads import limit_threads

if TYPE_CHECKING:
    from jointid.config.typed_diagnosis import DiagnoseJob


def _system_and_data(job: DiagnoseJob, dataset_path: str, matrices: str | None, model=None):
    limit_threads(1)
    model = model or load_model(matrices)
    system = build_system(model, job.settings.model)
    ds = read_dataset(dataset_path, measuring_points=system.meta["points"])
    return system, dataset_states(ds, system, job.settings, None if job.states is None else list(job.states))


def _kept_file(job: DiagnoseJob, subspace: str | None) -> str | None:
    """``subspace`` unless ``diagnosis.reuse_subspace`` is false (:mod:`jointid.fe.warmstart`)."""
    return subspace if job.reuse_subspace else None


def _warm(job: DiagnoseJob, system, subspace: str | None, log, basis: str | None = None) -> tuple:
    """What the last run kept at ``subspace``: its basis and a :class:`FitMemo` of its fits (an empty
    one when there is nothing to start from); ``(None, None)`` when ``diagnosis.reuse_subspace`` is
    false.  Without a kept basis, the shared one at ``basis`` (rule ``diagnosis_basis``) when it is
    this model's."""
    if _kept_file(job, subspace) is None:
        return load_basis(basis, system, log), None
    kept, why = warmstart.load(subspace, system, len(free_dofs(system.n_dofs, system.fixed)))
    log(f"diagnosis: {why}")
    memo = FitMemo(kept.fits if kept is not None else None)
    return (kept if kept is not None else load_basis(basis, system, log)), memo


def _keep(job: DiagnoseJob, system, subspace: str | None, res: Diagnosis, memo: FitMemo | None, log) -> None:
    if memo is not None and memo.hits:
        log(f"diagnosis: {memo.hits} of {memo.hits + memo.misses} fits asked exactly as in an earlier run: "
            "evaluated at the recorded optimum (re-checked there unless its check passed on the kept subspace), "
            "not searched again")
    if _kept_file(job, subspace) is not None and res.solver:
        warmstart.save(subspace, res.solver, system, memo.records if memo is not None else None, apart=True)


@contextmanager
def _figure_worker(log):
    """The page's figures in a process of their own (:class:`jointid.isolate.Worker`): started now, it imports
    matplotlib while the diagnosis runs, and draws while the drift fits run and the kept subspace is written; None where no process
    can be started (the figures are then drawn here)."""
    try:
        worker = isolate.Worker(*PRELOAD, what="the diagnosis page's figures", env={"MPLBACKEND": "Agg"})
    except OSError as exc:
        log(f"diagnosis: the figures are drawn in this process ({exc})")
        worker = None
    try:
        yield worker
    finally:
        if worker is not None:
            worker.close()


def _figures_made(painter, log) -> dict | None:
    """The figures the worker drew; None (drawn by the page itself) where its process failed."""
    if painter is None or not painter.asked:  # nothing handed to it: the page draws the figures
        return None
    try:
        return painter.result()
    except ModelError as exc:  # the process, not the figures: they are drawn here instead
        log(f"diagnosis: the figures are drawn in this process ({exc})")
        return None


def run_diagnosis(job: DiagnoseJob, dataset_name: str, dataset_path: str, matrices: str | None, out_dir: str, *,
                  history_csv: str | None = None, model=None, subspace: str | None = None,
                  basis: str | None = None, log=print_log) -> Diagnosis:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Workflow stage: diagnose one dataset and write ``out_dir`` (+ a row of ``history_csv``).

    ``job`` (:meth:`jointid.config.typed_diagnosis.DiagnoseJob.from_config`) is built from the sections ``rig,
    joints, solver, identify, effects, states, harmonic`` (the test band and drive point of the observability
    rule), ``diagnosis`` and ``dataset`` (the ``datasets.<name>`` entry: ``path``, ``states``); the model comes from ``matrices`` (the
    cached ``results/model/matrices.npz``) or ``model``.  ``subspace``: the file the reduced solver's
    final basis is kept in and the next run starts from (``diagnosis.reuse_subspace``); ``basis``: the
    run model's shared basis (rule ``diagnosis_basis``), the start when nothing is kept.
    """
    with _figure_worker(log) as painter:  # imports matplotlib beside the fits, draws beside the drift fits
        system, data = _system_and_data(job, dataset_path, matrices, model)
        kept, memo = _warm(job, system, subspace, log, basis)
        ready = None if painter is None else lambda **tables: painter.submit(figures, FigureData(**tables))
        res = diagnose(system, job.settings, data, start_basis=kept, memo=memo, tables_ready=ready, log=log)
        _keep(job, system, subspace, res, memo, log)
        figs = _figures_made(painter, log)
    h = job.config_hash
    run = {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": h,
           "n_dofs": system.n_dofs, "dataset_path": str(dataset_path), "states": [d.name for d in data]}
    write_outputs(res, out_dir, dataset_name, run, figs)
    if history_csv:
        append_history(history_csv, history_row(res, dataset_name, h))
    log(res.verdict)
    return res


def run_current(job: DiagnoseJob, dataset_path: str, matrices: str | None, out_dir: str, *, model=None,
                subspace: str | None = None, basis: str | None = None, log=print_log) -> Diagnosis:
    """Workflow stage (rule ``current``): the quick half of the loop of docs/effects.md.

    The baseline and the configured effects are calibrated exactly as the diagnosis does it (the same
    steps, so the same numbers), but no candidate is tested: ``out_dir`` gets ``ladder.csv``
    (baseline -> +each configured effect, per-state errors), ``current.csv`` (the current model
    against every measured mode) and ``compare.csv``.  Which effect is still missing is the full
    diagnosis' answer (``ranking.csv``).  ``subspace`` and ``basis`` as for :func:`run_diagnosis`.
    """
    system, data = _system_and_data(job, dataset_path, matrices, model)
    kept, memo = _warm(job, system, subspace, log, basis)
    res = diagnose(system, job.settings, data, candidates=[], drift=False, start_basis=kept, memo=memo, log=log)
    _keep(job, system, subspace, res, memo, log)
    out = Path(out_dir)
    io.write_csv(res.ladder, out / "ladder.csv")
    io.write_csv(res.current, out / "current.csv")
    io.write_csv(res.compare, out / "compare.csv")
    steps = res.ladder.groupby("variant", sort=False)["max_abs_error_pct"].max()
    log("current model: " + " -> ".join(f"{v} max {m:.2f} %" for v, m in steps.items()))
    return res
