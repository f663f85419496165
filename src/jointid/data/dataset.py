"""Measured modal data: reading, validating and writing a dataset folder.

A dataset is a folder holding

* ``modes.csv``       ``state,mode,freq_Hz[,damping_ratio][,freq_uncertainty_pct,damping_uncertainty_pct,
  shape_uncertainty_pct]`` -- one row per measured mode, modes numbered ``1..n`` per state in order of
  increasing frequency; the optional per-mode 1-sigma uncertainties (percent) come from an EMA;
* ``shapes.csv``      ``state,mode,point,direction,value`` (optional) -- real mode-shape values;
* ``frf.csv``         ``state,point,direction,freq_Hz,re,im`` (optional) -- receptance in m/N,
  drive point given per state in ``conditions.yaml``;
* ``conditions.yaml`` ``source``, optional ``frequency_uncertainty_pct`` and ``states:`` with, per
  state, ``em_force_N`` and optional ``currents``, ``motor_position_m``, ``frf_drive_point``,
  ``frf_drive_direction``.

See ``docs/measurement-format.md``.  Validation collects every problem, one line each, formatted
``<file>:<line or key path>: <what is wrong> — <how to fix it>``; :func:`read_dataset` raises them
together as one :class:`~jointid.errors.DataError`.  The checks of the files are in
:mod:`jointid.data.validate` (CSV files) and :mod:`jointid.data.conditions` (conditions.yaml); this
module holds the :class:`Dataset`, the checks across files, reading and writing.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from jointid.data.conditions import check_conditions, hz_confirmed
from jointid.data.validate import (COLUMNS, DIRECTIONS, CheckedModes, Problems, check_frf, check_modes, check_shapes,
                                   read_table)
from jointid.data.files import DATASET_FILES
from jointid.errors import DataError


@dataclass(frozen=True)
class Dataset:
    """A validated measured dataset.

    Attributes
    ----------
    name : str
        Folder name.
    modes : DataFrame
        Columns ``state, mode, freq_Hz`` (+ ``damping_ratio``, + the per-mode uncertainties
        ``freq_uncertainty_pct``, ``damping_uncertainty_pct``, ``shape_uncertainty_pct`` where given),
        sorted by state then mode.
    shapes : DataFrame or None
        Columns ``state, mode, point, direction, value``.
    frf : DataFrame or None
        Columns ``state, point, direction, freq_Hz, re, im``; receptance in m/N.
    conditions : dict
        The parsed ``conditions.yaml`` (keys ``source``, ``states``, ...).
    states : list of str
        States in order of first appearance in ``modes.csv``.
    """

    name: str
    modes: pd.DataFrame
    shapes: pd.DataFrame | None
    frf: pd.DataFrame | None
    conditions: dict
    states: list[str]

    def _check_state(self, state: str) -> None:
        if state not in self.states:
            raise DataError(f"dataset {self.name}: unknown state {state!r} — use one of "
                            f"{', '.join(self.states)}")

    def _modes_of(self, state: str) -> pd.DataFrame:
        self._check_state(state)
        return self.modes[self.modes["state"] == state].sort_values("mode")

    def freqs(self, state: str) -> np.ndarray:
        """Measured natural frequencies of ``state`` in Hz, shape ``(n_modes,)``, mode order."""
        return self._modes_of(state)["freq_Hz"].to_numpy(dtype=float)

    def damping(self, state: str) -> np.ndarray | None:
        """Damping ratios of ``state``, shape ``(n_modes,)``, or None if not measured."""
        if "damping_ratio" not in self.modes.columns:
            return None
        return self._modes_of(state)["damping_ratio"].to_numpy(dtype=float)

    def mode_uncertainty_pct(self, state: str, kind: str = "freq") -> np.ndarray | None:
        """Per-mode 1-sigma uncertainty of ``state`` in percent, shape ``(n_modes,)``, mode order; None if
        modes.csv has no ``<kind>_uncertainty_pct`` column (``kind``: ``freq``, ``damping`` or ``shape``).

        The values are relative: of the frequency, of the damping ratio, or of the RMS of the mode's shape
        values (as conditions.yaml's global keys).  An EMA writes them (jointid.ema).
        """
        if kind not in ("freq", "damping", "shape"):
            raise DataError(f"uncertainty kind {kind!r} is not freq, damping or shape — use one of them")
        col = f"{kind}_uncertainty_pct"
        if col not in self.modes.columns:
            return None
        return self._modes_of(state)[col].to_numpy(dtype=float)

    def frequency_sigma_rel(self, state: str) -> np.ndarray | None:
        """Per-mode relative 1-sigma of the natural frequencies of ``state`` (0.01 = 1 %), shape
        ``(n_modes,)``, mode order; None when modes.csv has no ``freq_uncertainty_pct`` (then the global
        ``frequency_uncertainty_pct`` of conditions.yaml, default 1 %, applies)."""
        pct = self.mode_uncertainty_pct(state, "freq")
        return None if pct is None else pct / 100.0

    def frequency_variance(self, state: str, default_pct: float = 1.0) -> np.ndarray:
        """Per-mode variance of the relative frequency error of ``state``, ``(sigma_rel)^2``, shape
        ``(n_modes,)``: from ``freq_uncertainty_pct`` where given, else conditions.yaml's
        ``frequency_uncertainty_pct``, else ``default_pct`` (the config's ``identify.frequency_uncertainty_pct``
        in the fits), the same for every mode."""
        rel = self.frequency_sigma_rel(state)
        if rel is None:
            pct = float(self.conditions.get("frequency_uncertainty_pct", default_pct))
            rel = np.full(len(self.freqs(state)), pct / 100)
        return rel**2

    def state_conditions(self, state: str) -> dict:
        """The ``conditions.yaml`` entry of ``state`` (``em_force_N`` etc.)."""
        self._check_state(state)
        return dict(self.conditions["states"][state])

    def shape_matrix(self, state: str, point_dof_labels) -> np.ndarray:
        """Measured mode shapes of ``state`` at the given point DOFs.

        Parameters
        ----------
        state : str
        point_dof_labels : sequence of str or (point, direction) tuples
            Labels ``"<point>:<direction>"``, e.g. ``"T05:y"``.

        Returns
        -------
        ndarray, shape ``(n_labels, n_modes)``
            Shape values; NaN where a label was not measured (or no shapes.csv).
        """
        labels = [_split_label(lab) for lab in point_dof_labels]
        modes = self._modes_of(state)["mode"].to_numpy(dtype=int)
        out = np.full((len(labels), len(modes)), np.nan)
        if self.shapes is None:
            return out
        sh = self.shapes[self.shapes["state"] == state]
        lookup = {(p, d, int(m)): v for p, d, m, v in
                  zip(sh["point"], sh["direction"], sh["mode"], sh["value"])}
        col = {int(m): j for j, m in enumerate(modes)}
        for i, (p, d) in enumerate(labels):
            for m, j in col.items():
                out[i, j] = lookup.get((p, d, m), np.nan)
        return out

    def frf_curve(self, state: str, point: str, direction: str) -> tuple[np.ndarray, np.ndarray]:
        """Receptance at ``point``/``direction``: ``(freq_Hz (n,), H (n,) complex, m/N)``."""
        self._check_state(state)
        if self.frf is None:
            return np.empty(0), np.empty(0, complex)
        f = self.frf
        sel = f[(f["state"] == state) & (f["point"] == point) & (f["direction"] == direction)]
        sel = sel.sort_values("freq_Hz")
        return (sel["freq_Hz"].to_numpy(float),
                sel["re"].to_numpy(float) + 1j * sel["im"].to_numpy(float))


def _split_label(label) -> tuple[str, str]:
    if isinstance(label, tuple) and len(label) == 2:
        point, direction = label
    elif isinstance(label, str) and label.count(":") == 1:
        point, direction = label.split(":")
    else:
        raise DataError(f"point DOF label {label!r} is not '<point>:<direction>' — write e.g. 'T05:y'")
    if direction not in DIRECTIONS:
        raise DataError(f"point DOF label {label!r}: direction {direction!r} is not x, y or z — "
                        "write e.g. 'T05:y'")
    return str(point), direction


# ---------------------------------------------------------------------------------------- dataset
def modes_states(folder) -> list[str] | None:
    """State names in ``folder/modes.csv`` (each once), without checking the rows.

    A cheap look for the configuration check (does the dataset hold the states that use it?);
    :func:`read_dataset` does the full validation.  None if there is no readable modes.csv with a
    ``state`` column.
    """
    counts = modes_per_state(folder)
    return None if counts is None else list(counts)


def modes_per_state(folder) -> dict[str, int] | None:
    """Number of rows of each state in ``folder/modes.csv`` (in order of first appearance), without
    checking the rows; None if there is no readable modes.csv with a ``state`` column."""
    path = Path(folder) / "modes.csv"
    try:
        table = read_table(path, str(path), Problems()) if path.is_file() else None
    except OSError:
        return None
    if table is None:
        return None
    _, rows, _, rejected = table
    counts: dict[str, int] = {}
    for row in [r for _, r in rows] + rejected:
        state = (row.get("state") or "").strip()
        if state:
            counts[state] = counts.get(state, 0) + 1
    return counts


def _point_names(measuring_points, problems):
    if measuring_points is None:
        return None
    if "point" not in getattr(measuring_points, "columns", ()):
        problems.add("measuring_points:1", "missing column 'point'",
                     "pass the table with columns point, x_m, y_m, z_m")
        return None
    return set(map(str, measuring_points["point"]))


def _load(folder, measuring_points=None, expected_states=None):
    problems = Problems()
    folder = Path(folder)
    if not folder.exists():
        problems.add(str(folder), "dataset folder does not exist",
                     "check the path (a dataset is a folder with modes.csv and conditions.yaml)")
        return problems, None
    if not folder.is_dir():
        problems.add(str(folder), "is a file, not a folder",
                     "pass the folder that holds modes.csv and conditions.yaml")
        return problems, None
    points = _point_names(measuring_points, problems)
    label = lambda name: str(folder / name)  # noqa: E731
    modes, shapes, frf = CheckedModes(None, [], set()), None, None
    if (folder / "modes.csv").is_file():
        modes = check_modes(folder / "modes.csv", label("modes.csv"), problems,
                            hz_confirmed=hz_confirmed(folder / "conditions.yaml"))
    else:
        problems.add(label("modes.csv"), "file is missing",
                     "add modes.csv with columns state,mode,freq_Hz")
    if (folder / "shapes.csv").is_file():
        shapes = check_shapes(folder / "shapes.csv", label("shapes.csv"), problems, modes, points)
    if (folder / "frf.csv").is_file():
        frf = check_frf(folder / "frf.csv", label("frf.csv"), problems, modes, points)
    frf_states = set() if frf is None else set(frf["state"])
    conditions = None
    if (folder / "conditions.yaml").is_file():
        conditions = check_conditions(folder / "conditions.yaml", label("conditions.yaml"),
                                       problems, points, frf_states)
    else:
        problems.add(label("conditions.yaml"), "file is missing",
                     "add conditions.yaml with 'source:' and 'states:' (em_force_N per state)")
    mode_states = modes.states
    cond_states = None
    if isinstance(conditions, dict) and isinstance(conditions.get("states"), dict):
        cond_states = [str(s) for s in conditions["states"]]
    if modes.df is not None and cond_states is not None:
        for s in mode_states:
            if s not in cond_states:
                problems.add(f"{label('conditions.yaml')}:states", f"state {s!r} of modes.csv is "
                             "missing", f"add states.{s} with em_force_N")
        for s in cond_states:
            if s not in mode_states:
                problems.add(f"{label('conditions.yaml')}:states.{s}", "state is not in modes.csv",
                             f"fix the name (states: {', '.join(mode_states)}) or remove it")
    for s in expected_states or ():
        if modes.df is not None and s not in mode_states:
            problems.add(label("modes.csv"), f"expected state {s!r} has no modes",
                         f"add its modes or measure state {s}")
        if cond_states is not None and s not in cond_states:
            problems.add(f"{label('conditions.yaml')}:states", f"expected state {s!r} is missing",
                         f"add states.{s} with em_force_N")
    if problems:
        return problems, None
    if isinstance(conditions.get("states"), dict):
        conditions["states"] = {str(k): v for k, v in conditions["states"].items()}
    order = {s: i for i, s in enumerate(mode_states)}
    df = modes.df
    modes = (df.assign(_o=df["state"].map(order)).sort_values(["_o", "mode"])
             .drop(columns="_o").reset_index(drop=True))
    return problems, Dataset(name=folder.resolve().name, modes=modes,
                             shapes=shapes if shapes is not None and len(shapes) else None,
                             frf=frf if frf is not None and len(frf) else None,
                             conditions=conditions, states=mode_states)


def validate_dataset(folder, measuring_points=None, expected_states=None) -> list[str]:
    """Check a dataset folder; return every problem as one line (empty list if valid).

    Parameters
    ----------
    folder : path
        Dataset folder.
    measuring_points : DataFrame, optional
        Columns ``point, x_m, y_m, z_m``; when given, point names in shapes.csv, frf.csv and
        ``frf_drive_point`` must appear in it.
    expected_states : sequence of str, optional
        States that must be present in modes.csv and conditions.yaml.
    """
    return _load(folder, measuring_points, expected_states)[0].condensed()


def read_dataset(folder, measuring_points=None, expected_states=None) -> Dataset:
    """Read and validate a dataset folder; raise one :class:`DataError` listing every problem."""
    problems, dataset = _load(folder, measuring_points, expected_states)
    if problems:
        raise DataError(problems.condensed())
    return dataset


def write_dataset(folder, modes: pd.DataFrame, shapes: pd.DataFrame | None = None,
                  frf: pd.DataFrame | None = None, *, conditions: dict,
                  measuring_points=None) -> Dataset:
    """Write a dataset folder atomically and return it (as read from the files written).

    The files are written into a temporary sibling folder which is validated and then renamed to
    ``folder`` (an existing dataset folder is replaced: renamed aside, swapped, then deleted), so a
    reader never sees a half-written dataset.  Nothing is written if validation fails; a folder
    holding files other than dataset files is never replaced.

    Parameters
    ----------
    folder : path
    modes : DataFrame
        ``state, mode, freq_Hz`` (+ ``damping_ratio``).
    shapes, frf : DataFrame, optional
        ``state, mode, point, direction, value`` / ``state, point, direction, freq_Hz, re, im``.
    conditions : dict
        Content of conditions.yaml: ``{"source": ..., "states": {state: {"em_force_N": ...}}}``.
    measuring_points : DataFrame, optional
        Used to validate point names before the swap.

    Raises
    ------
    DataError
        If the data are invalid or ``folder`` holds foreign files.
    """
    folder = Path(folder)
    if folder.exists():
        foreign = sorted(p.name for p in folder.iterdir() if p.name not in DATASET_FILES)
        if not folder.is_dir() or foreign:
            raise DataError(f"{folder}: exists and holds files that are not dataset files "
                            f"({', '.join(foreign) or 'it is a file'}) — write to a new folder or "
                            "move them away")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=folder.parent))
    try:
        _frame_to_csv(modes, COLUMNS["modes.csv"], tmp / "modes.csv")
        if shapes is not None:
            _frame_to_csv(shapes, COLUMNS["shapes.csv"], tmp / "shapes.csv")
        if frf is not None:
            _frame_to_csv(frf, COLUMNS["frf.csv"], tmp / "frf.csv")
        with open(tmp / "conditions.yaml", "w", encoding="utf-8") as fh:
            yaml.safe_dump(_plain(conditions), fh, sort_keys=False, allow_unicode=True)
        found, dataset = _load(tmp, measuring_points)
        if found:
            raise DataError([p.replace(str(tmp), str(folder)) for p in found.condensed()])
        _swap_in(tmp, folder)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    # the files checked in the temporary folder are the ones now in ``folder``: its dataset, not a second read
    return replace(dataset, name=folder.resolve().name)


def _frame_to_csv(df, columns, path):
    required, optional = columns
    cols = list(required) + [c for c in optional if c in df.columns]
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise DataError(f"{path.name}: table to write lacks column(s) {', '.join(missing)} — "
                        f"provide {', '.join(required)}")
    df.loc[:, cols].to_csv(path, index=False, lineterminator="\n")


def _plain(obj):
    """Convert numpy scalars and containers into plain Python for yaml.safe_dump."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _swap_in(tmp: Path, folder: Path) -> None:
    if not folder.exists():
        os.replace(tmp, folder)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.old-", dir=folder.parent))
    old.rmdir()
    os.replace(folder, old)
    try:
        os.replace(tmp, folder)
    except OSError:
        os.replace(old, folder)
        raise
    shutil.rmtree(old)
