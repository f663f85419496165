"""Measured datasets in the configuration: the one state → dataset rule and its checks.

A state reads the dataset ``states.<state>.dataset`` (a name in ``datasets``, else a folder),
else ``measurements.dataset`` (:func:`dataset_folder`); the diagnosis reads every dataset under
``datasets:``, else the run's measured dataset (:func:`registered_datasets`).  The checks here
(:func:`check_states`, :func:`check_dataset_folders`, :func:`check_mode_counts`) run through the
:class:`~jointid.config.checks.Checks` context of :func:`jointid.config.load.check_config`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from jointid.config.checks import Checks, Skip
from jointid.config.messages import suggest

__all__ = [
    "check_dataset_folders",
    "check_mode_counts",
    "check_states",
    "dataset_folder",
    "registered_datasets",
    "states_and_datasets",
]


# ------------------------------------------------------------------ the state -> dataset rule
def dataset_folder(cfg: dict, state: str) -> str:
    """Dataset folder of ``state``: ``states.<state>.dataset`` (a folder or a name in ``datasets``),
    else ``measurements.dataset``."""
    name = (cfg.get("states", {}).get(state) or {}).get("dataset")
    if name:
        named = cfg.get("datasets", {}).get(name)
        return named["path"] if named else name
    return cfg.get("measurements", {}).get("dataset", "data/paper")


def registered_datasets(config: dict) -> dict:
    """The datasets to diagnose: those under `datasets:`, else the measured dataset of the run.

    Without a `datasets:` block the folder `measurements.dataset` (the paper's data by default) is
    diagnosed under its folder name, with the states that use it.
    """
    named = dict(config.get("datasets") or {})
    if named:
        return named
    path = config["measurements"]["dataset"]
    states = [s for s, c in config["states"].items() if not c.get("dataset")]
    name = os.path.basename(os.path.normpath(path))
    if not states or not name.isidentifier():
        return {}
    return {name: {"path": path, "states": states}}


# ------------------------------------------------------------------------------------ checks
def states_and_datasets(c: Checks) -> tuple[Mapping, Mapping] | None:
    """The ``states`` and ``datasets`` sections, or None when either is missing or malformed."""
    try:
        states, datasets = c.get("states"), c.get("datasets")
    except Skip:
        return None
    if not isinstance(states, Mapping) or not isinstance(datasets, Mapping):
        return None
    return states, datasets


def check_states(c: Checks) -> None:
    """Every state listed under ``datasets.<name>.states`` is a state of ``states``."""
    sections = states_and_datasets(c)
    if sections is None:
        return
    states, datasets = sections
    for dname, ds in datasets.items():
        if not isinstance(ds, Mapping) or not isinstance(ds.get("states"), list):
            continue
        for i, sname in enumerate(ds["states"]):
            if isinstance(sname, str) and sname not in states:
                guess = suggest(sname, states)
                advice = f"did you mean {guess!r}?" if guess else f"use one of: {', '.join(states)}"
                c.add(["datasets", dname, "states", i], f"{sname!r} is not in states — {advice}")


def _folder_problem(path: str) -> str | None:
    """Why ``path`` is not a dataset folder, or None if it is a folder."""
    if Path(path).is_dir():
        return None
    return "is a file, not a folder" if Path(path).exists() else "is not an existing folder"


def _check_named_paths(c: Checks, named: Mapping, here: str) -> None:
    """Every ``datasets.<name>.path`` is an existing folder."""
    for dname, ds in named.items():
        path = ds.get("path") if isinstance(ds, Mapping) else None
        if not isinstance(path, str) or ("datasets", str(dname), "path") in c.bad:
            continue
        problem = _folder_problem(path)
        if problem:
            c.add(["datasets", dname, "path"], f"{path!r} {problem} ({here}) — give the folder that holds "
                  "the dataset's modes.csv and conditions.yaml")


def _validate_contents(c: Checks, by_state: dict[str, str], named: Mapping, states: Mapping, checked) -> None:
    """Every dataset folder the run reads, validated in full before any job
    (:func:`jointid.data.dataset.validate_dataset`: units, columns, separators, conditions.yaml; ``checked(path)``
    gives its answer, :func:`jointid.data.checked.folder_checks`), each problem under the config key that names
    the folder.  Measuring-point names are checked later, by the stage reading the dataset with the model's points."""
    keys: dict[str, str] = {}
    for dname, ds in named.items():
        if isinstance(ds, Mapping) and isinstance(ds.get("path"), str):
            keys.setdefault(ds["path"], f"datasets.{dname}.path")
    for sname, path in by_state.items():
        value = states[sname].get("dataset") if isinstance(states.get(sname), Mapping) else None
        keys.setdefault(path, f"states.{sname}.dataset" if value == path else "measurements.dataset")
    for path, key in keys.items():
        if not Path(path).is_dir():
            continue  # reported by the folder checks
        for line in checked(path)[1]:
            c.add(key, f"the dataset has a problem: {line}")


def _state_folders(c: Checks, states: Mapping, named: Mapping, here: str) -> dict[str, str]:
    """Folder of each state whose dataset folder exists (the rule of :func:`dataset_folder`,
    checked); a problem is noted for each state whose dataset is missing."""
    default_users = []
    by_state: dict[str, str] = {}
    for sname, state in states.items():
        if not isinstance(state, Mapping) or ("states", str(sname), "dataset") in c.bad:
            continue
        value = state.get("dataset")
        if value is None:
            default_users.append(sname)
            continue
        if not isinstance(value, str):
            continue
        if value in named:
            path = named[value].get("path") if isinstance(named[value], Mapping) else None
            if isinstance(path, str):
                by_state[sname] = path
            continue
        problem = _folder_problem(value)
        if problem is None:
            by_state[sname] = value
            continue
        guess = suggest(value, named)
        if guess:
            advice = f"did you mean {guess!r}?"
        elif named:
            advice = f"use one of the datasets {', '.join(named)} or the path of a dataset folder ({here})"
        else:
            advice = (f"register it under datasets ({value}: {{path: <folder>, states: [{sname}]}}) or give "
                      f"the path of a dataset folder ({here})")
        c.add(["states", sname, "dataset"], f"{value!r} is neither a name in datasets nor an existing folder — {advice}")

    if default_users:
        try:
            path = c.get("measurements.dataset")
        except Skip:
            path = None
        if isinstance(path, str):
            problem = _folder_problem(path)
            if problem:
                c.add("measurements.dataset", f"{path!r} {problem} ({here}; used by "
                      f"{', '.join(map(str, default_users))}) — give the folder that holds the measured "
                      "modes.csv and conditions.yaml, or run from the folder it is relative to")
            else:
                for sname in default_users:
                    by_state[sname] = path
    return by_state


def check_dataset_folders(c: Checks) -> None:
    """The measured datasets the run reads exist, and hold the states that use them.

    A state reads ``states.<s>.dataset`` (a name in ``datasets``, else a folder), else
    ``measurements.dataset``; every ``datasets.<n>.path`` is read by the diagnosis.  Folders are
    relative to the working directory (as in the workflow).  Only the state names of each
    ``modes.csv`` are read here; the full validation of a dataset stays with the stage reading it.  Both
    answers of a folder are remembered by its content (:mod:`jointid.data.checked`: a Snakemake start does
    not import pandas to read unchanged folders again).
    """
    from jointid.data.checked import folder_checks

    sections = states_and_datasets(c)
    if sections is None:
        return
    states, named = sections
    here = f"relative to the working directory {Path.cwd()}"
    _check_named_paths(c, named, here)
    by_state = _state_folders(c, states, named, here)

    # states without modes in their dataset (a cheap look at modes.csv's state column)
    answers: dict[str, tuple] = {}

    def checked(path: str) -> tuple:
        if path not in answers:
            answers[path] = folder_checks(path)
        return answers[path]

    def states_in(path: str) -> dict[str, int] | None:
        return checked(path)[0] if Path(path).is_dir() else None

    for sname, path in by_state.items():
        found = states_in(path)
        if found is not None and sname not in found:
            guess = suggest(sname, [f for f in found if f not in states])
            hint = f" (did you mean {guess!r}? rename the state)" if guess else ""
            c.add(["states", sname], f"dataset {path} has no modes of state {sname!r} in modes.csv (its states: "
                  f"{', '.join(found) or 'none'}){hint} — measure it there, or set states.{sname}.dataset to a "
                  "dataset that holds it")
    check_mode_counts(c, {s: states_in(p).get(s) for s, p in by_state.items() if states_in(p)})
    _validate_contents(c, by_state, named, states, checked)
    for dname, ds in named.items():
        if not isinstance(ds, Mapping) or not isinstance(ds.get("path"), str) or not isinstance(ds.get("states"), list):
            continue
        found = states_in(ds["path"])
        if found is None:
            continue
        for i, sname in enumerate(ds["states"]):
            if isinstance(sname, str) and sname in states and sname not in found:
                c.add(["datasets", dname, "states", i], f"{sname!r} has no modes in {ds['path']}/modes.csv (its "
                      f"states: {', '.join(found) or 'none'}) — remove it from the list, or add its modes")


def check_mode_counts(c: Checks, counts: dict[str, int | None]) -> None:
    """One weight per measured mode, and enough model modes to pair them, before any solve runs."""
    counts = {s: n for s, n in counts.items() if n}
    if not counts:
        return
    try:
        weights = c.get("identify.weights")
        if isinstance(weights, list) and weights:
            wrong = {s: n for s, n in counts.items() if n != len(weights)}
            if wrong:
                c.add("identify.weights", f"{len(weights)} weights, but the datasets measure "
                      + ", ".join(f"{n} mode{'s' * (n != 1)} of {s}" for s, n in wrong.items())
                      + " — give one weight per measured mode, or [] for all 1")
    except Skip:
        pass
    try:
        n_modes = c.get("solver.n_modes")
        most = max(counts.values())
        if isinstance(n_modes, int) and not isinstance(n_modes, bool) and n_modes < most:
            state = max(counts, key=counts.get)
            c.add("solver.n_modes", f"{n_modes} model modes cannot pair the {most} measured modes of {state} — "
                  f"use n_modes >= {most} (a few more, so that the pairing can skip modes the test did not see)")
    except Skip:
        pass
