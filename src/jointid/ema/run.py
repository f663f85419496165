"""The EMA from an FRF source to a dataset folder and the engineer's files.

:func:`run_ema` reads the FRFs (:func:`jointid.ema.sources.load_frfs`), runs the EMA of every state
(:func:`jointid.ema.extract.extract_state`), and only then writes: the dataset folder (atomically, by
:func:`jointid.data.dataset.write_dataset`, validated before it appears) and, in the report folder,
``poles.csv`` (the pole table of every state), ``stabilisation_<state>.png`` and ``frf_<state>.png``.
Any error leaves no dataset behind.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from jointid.data.dataset import Dataset, write_dataset
from jointid.ema.extract import StateEma, dataset_tables, extract_state, pole_table
from jointid.ema.figures import frf_overlay, stabilisation_chart
from jointid.ema.frfs import FrfSet
from jointid.ema.sources import load_frfs
from jointid.ema.options import EmaOptions
from jointid.io import write_csv

__all__ = ["run_ema", "ema_of", "default_report"]


def default_report(out) -> Path:
    """The report folder beside a dataset folder ``out``: ``<out>_ema``."""
    out = Path(out)
    return out.with_name(out.name + "_ema")


def ema_of(frfs: dict[str, FrfSet], options: EmaOptions, log=print) -> list[StateEma]:
    """The EMA of every state of ``frfs`` (in their order), each with its own bootstrap seed stream."""
    return [extract_state(fs, options, log=log, stream=k) for k, fs in enumerate(frfs.values())]


def run_ema(source, out, *, report=None, options: EmaOptions | None = None, state: str = "measured",
            measuring_points: pd.DataFrame | None = None, em_force_N: float | None = None,
            log=print) -> tuple[Dataset, list[StateEma]]:
    # many parameters: source, outputs, options, the state name of a UFF file, the model's points, the force, log
    """EMA of the FRFs at ``source`` (frf.csv, UFF 58 or a dataset folder) into the dataset folder ``out``.

    Parameters
    ----------
    source : path
        frf.csv, hammer time histories (CSV with ``time_s``), UFF 58 or a dataset folder with frf.csv.
    out : path
        Dataset folder to write (replaced atomically when it is a dataset folder already).
    report : path, optional
        Folder of poles.csv and the figures; default ``<out>_ema``.
    options : EmaOptions, optional
        Default: the schema's ``ema`` defaults.
    state : str
        State name of a UFF file's FRFs (CSV and dataset folders name their states).
    measuring_points : DataFrame, optional
        The model's measuring points; point names are checked against them before anything is written,
        and a UFF file's nodes are mapped to them.
    em_force_N : float, optional
        Motor attraction of every state when the source does not give it (default 0.0).
    log : callable
        Receives the progress lines.

    Returns
    -------
    (Dataset, list of StateEma)
    """
    options = options or EmaOptions.from_section()
    frfs, conditions = load_frfs(source, state=state, coherence_min=options.coherence_min,
                                 max_low_fraction=options.max_low_coherence_fraction,
                                 measuring_points=measuring_points, log=log)
    log(f"read {sum(fs.H.shape[0] for fs in frfs.values())} FRFs of {len(frfs)} state(s) from {source}")
    results = ema_of(frfs, options, log=log)
    tables = dataset_tables(results, conditions, Path(source).name)
    if em_force_N is not None:
        for cond in tables["conditions"]["states"].values():
            cond["em_force_N"] = float(em_force_N)
    dataset = write_dataset(out, tables["modes"], tables["shapes"], tables["frf"], conditions=tables["conditions"],
                            measuring_points=measuring_points)
    report = Path(report) if report is not None else default_report(out)
    write_csv(pd.concat([pole_table(r) for r in results], ignore_index=True), report / "poles.csv")
    for r in results:
        stabilisation_chart(r, report / f"stabilisation_{r.frfs.state}.png")
        frf_overlay(r, report / f"frf_{r.frfs.state}.png")
    log(f"wrote dataset {out} ({', '.join(f'{r.frfs.state}: {len(r.refined)} modes' for r in results)}) "
        f"and {report}/poles.csv, stabilisation_<state>.png, frf_<state>.png")
    return dataset, results
