"""Workflow stage of the diagnosis: read a dataset and the model, diagnose, write the results.

Called by ``workflow/scripts/diagnose.py`` (rule ``diagnose``) and by the command line
``python -m jointid.diagnosis``; see docs/effects.md.
"""

from __future__ import annotations

import time

from jointid.config import config_hash
from jointid.data.dataset import read_dataset
from jointid.diagnosis.fitting import print_log
from jointid.diagnosis.history import append_history, history_row
from jointid.diagnosis.loop import Diagnosis, diagnose
from jointid.diagnosis.outputs import write_outputs
from jointid.diagnosis.terms import build_system
from jointid.diagnosis.variants import dataset_states
from jointid.fe.model import load_model
from jointid.threads import limit_threads


def run_diagnosis(cfg: dict, dataset_name: str, dataset_path: str, matrices: str | None, out_dir: str, *,
                  history_csv: str | None = None, model=None, log=print_log) -> Diagnosis:
    """Workflow stage: diagnose one dataset and write ``out_dir`` (+ a row of ``history_csv``).

    ``cfg`` holds the sections ``rig, joints, solver, identify, effects, states, harmonic`` (the test
    band and drive point of the observability rule) and ``dataset``
    (the ``datasets.<name>`` entry: ``path``, ``states``); the model comes from ``matrices`` (the
    cached ``results/model/matrices.npz``) or ``model``.
    """
    limit_threads(1)
    model = model or load_model(matrices)
    system = build_system(model, cfg)
    ds = read_dataset(dataset_path, measuring_points=system.meta["points"])
    entry = cfg.get("dataset") or {}
    data = dataset_states(ds, system, cfg, entry.get("states"))
    res = diagnose(system, cfg, data, log=log)
    h = config_hash({k: v for k, v in cfg.items() if k != "dataset"})
    run = {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": h,
           "n_dofs": system.n_dofs, "dataset_path": str(dataset_path), "states": [d.name for d in data]}
    write_outputs(res, out_dir, dataset_name, run)
    if history_csv:
        append_history(history_csv, history_row(res, dataset_name, h))
    log(res.verdict)
    return res
