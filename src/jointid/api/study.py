"""The :class:`Study`: one validated configuration, its FE model, and the engineer's procedure on it.

Every method calls the functions the Snakemake stages call (see each method's notes); nothing here
re-implements a stage.  The model, the diagnosis system and the diagnosis' reduced solver are built
once per study and reused.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Mapping, Sequence
from contextlib import contextmanager, redirect_stdout
from pathlib import Path
from typing import TYPE_CHECKING, Union

import numpy as np
import pandas as pd

import jointid.api.measured as measured
from jointid.api.results import DiagnosisResult, Identification, MethodResult, ModalResult
from jointid.config.study import StudySettings
from jointid.errors import DataError

if TYPE_CHECKING:
    from jointid.data.dataset import Dataset

__all__ = ["Study"]

ConfigSource = Union[str, os.PathLike, Mapping, Sequence]
"""A YAML file, a loaded mapping, or YAML files merged in order."""
DatasetLike = Union[str, os.PathLike, "Dataset"]
"""A dataset folder, a ``.uff``/``.unv`` file, or a :class:`jointid.data.dataset.Dataset`."""


def _quiet(msg: str) -> None:
    """A log that drops every line."""


class _Lines(io.TextIOBase):
    """A text stream that hands each complete line written to it to ``log``."""

    def __init__(self, log: Callable[[str], None]):
        super().__init__()
        self._log, self._part = log, ""

    def write(self, text: str) -> int:
        *lines, self._part = (self._part + text).split("\n")
        for line in lines:
            self._log(line)
        return len(text)


@contextmanager
def _progress(log: Callable[[str], None]):
    """The stages' progress lines (printed, as in the rules' logs) handed to ``log`` instead."""
    with redirect_stdout(_Lines(log)):
        yield


class Study:
    """A rig configuration and what the engineer does with it: modes, compare, identify, run the method,
    diagnose.

    Build one with :meth:`from_config` (YAML files or a mapping), :meth:`default` (the shipped defaults) or
    ``Study(settings)`` (typed :class:`jointid.config.study.StudySettings`).  Units are SI throughout: joint parameters in N/m^3
    (``k_normal_N_per_m3`` ...), frequencies in Hz, coordinates in m.

    Examples
    --------
    >>> from jointid import Study
    >>> study = Study.from_config(["config.yaml", "tests/coarse_config.yaml"])  # doctest: +SKIP
    >>> study.modes(n=6).table()                                                # doctest: +SKIP
    """

    def __init__(self, settings: StudySettings):
        """Wrap the settings of an already validated configuration
        (``StudySettings.from_config(load_config(...))``, :class:`jointid.config.study.StudySettings`); prefer
        :meth:`from_config`."""
        self._study = settings
        self._settings = settings.settings  # the typed objects the domain layers take
        self._model = None
        self._system = None
        self._solver = None
        self._identified: dict[str, Identification] = {}
        self._found: dict[str, dict[str, float]] = {}  # run_method's parameters per state

    # ------------------------------------------------------------------ set-up
    @classmethod
    def from_config(cls, path_or_dict: ConfigSource, overrides: Mapping | None = None) -> Study:
        """Load, default and validate a configuration.

        Parameters
        ----------
        path_or_dict : path, mapping, or sequence of paths
            A YAML file (``config.yaml``), an already loaded mapping, or several YAML files merged in
            order, later files winning key by key (as ``snakemake --configfile a.yaml b.yaml``), e.g.
            ``["config.yaml", "tests/coarse_config.yaml"]`` for the coarse test mesh.
        overrides : mapping, optional
            Deep-merged on top before validation; dotted keys work (``{"mesh.refine": 2}``) and a
            ``None`` value removes the key (``{"joints": {"parameters": {"k_feed_N_per_m3": None}}}``).

        Returns
        -------
        Study

        Raises
        ------
        jointid.errors.ConfigError
            One line per problem, all problems together.
        """
        from jointid.config import load_config
        from jointid.yamlio import read_merged

        if isinstance(path_or_dict, Sequence) and not isinstance(path_or_dict, (str, bytes)):
            raw, source = read_merged(path_or_dict), " + ".join(map(str, path_or_dict))
            return cls(StudySettings.from_config(load_config(raw, overrides, source=source)))
        return cls(StudySettings.from_config(load_config(path_or_dict, overrides)))

    @classmethod
    def default(cls, overrides: Mapping | None = None) -> Study:
        """The study of the shipped defaults (the configuration schema's: the paper's rig, joints and
        data in ``data/paper``, relative to the working folder), with ``overrides`` deep-merged on top as in
        :meth:`from_config`; no file is read."""
        from jointid.config import load_config

        return cls(StudySettings.from_config(load_config({}, overrides, source="the shipped defaults")))

    @property
    def config(self) -> dict:
        """The validated configuration (every default filled in).  Treat it as read-only: the cached
        model was built from it."""
        return self._study.config

    def parameters(self) -> pd.DataFrame:
        """The joint parameters: one row each, columns ``parameter, identified, lower_N_per_m3,
        upper_N_per_m3, default_N_per_m3`` (the default of an identified parameter is the geometric
        mean of its bounds, of a fixed one its ``joints.fixed`` value)."""
        joints = self._settings.model.joints
        rows = [{"parameter": p.name, "identified": True, "lower_N_per_m3": float(p.lower_N_per_m3),
                 "upper_N_per_m3": float(p.upper_N_per_m3), "default_N_per_m3": p.default_N_per_m3}
                for p in joints.parameters]
        rows += [{"parameter": n, "identified": False, "lower_N_per_m3": np.nan, "upper_N_per_m3": np.nan,
                  "default_N_per_m3": float(v)} for n, v in joints.fixed_N_per_m3.items()]
        return pd.DataFrame(rows)

    def theta(self, state: str | None = None, theta: Mapping[str, float] | None = None) -> dict[str, float]:
        """Every joint parameter in N/m^3: the defaults (:meth:`parameters`), then what
        :meth:`identify` (else :meth:`run_method`) found for ``state`` in this study, then ``theta`` on top.

        Raises
        ------
        jointid.errors.ConfigError
            If ``theta`` names a parameter the configuration does not have.
        """
        from jointid.errors import ConfigError

        table = self.parameters()
        values = dict(zip(table["parameter"], table["default_N_per_m3"]))
        if state in self._identified:
            values.update(self._identified[state].theta)
        elif state in self._found:
            values.update(self._found[state])
        unknown = sorted(set(theta or {}) - set(values))
        if unknown:
            raise ConfigError(f"theta: {', '.join(unknown)} is not a joint parameter — use one of "
                              f"{', '.join(values)} (joints.parameters and joints.fixed)")
        values.update({k: float(v) for k, v in (theta or {}).items()})
        return {k: float(v) for k, v in values.items()}

    def model(self):
        """The FE model of the rig (:class:`jointid.fe.fem.Model`), built once by rule ``mesh``'s
        :func:`jointid.stages.model.mesh_model` and held as its ``matrices.npz`` holds it
        (:func:`jointid.fe.model.stored_model`), so that it solves as the workflow's does.

        Its stiffness and mass are affine in the joint parameters: ``K = K0 + sum c_t K_t``,
        ``M = M0 + sum c_t M_t`` over the terms of ``model.stiffness`` / ``model.mass`` (sparse,
        ``(n_dofs, n_dofs)``); ``model.probe`` ``(n_labels, n_dofs)`` picks the displacements at the
        measuring points.
        """
        if self._model is None:
            from jointid.fe.model import stored_model
            from jointid.stages.method import MethodOptions
            from jointid.stages.model import mesh_model

            with _progress(_quiet):
                self._model = stored_model(mesh_model(MethodOptions.of(self._study).mesh))
        return self._model

    def points(self) -> pd.DataFrame:
        """The measuring points: columns ``point, x_m, y_m, z_m`` (+ the rig's own columns)."""
        return pd.DataFrame(self.model().meta["points"])

    def dataset(self, source: str | os.PathLike, *, state: str = "power_off",
                em_force_N: float | None = None) -> Dataset:
        """A measured dataset (:class:`jointid.data.dataset.Dataset`) checked against this rig's
        measuring points: a folder in the format of docs/measurement-format.md, or a UFF file
        (``.uff``/``.unv``, imported as ``state`` by :func:`jointid.data.uff.import_uff`, nodes
        mapped to the measuring points by their coordinates)."""
        return measured.load(source, self.points(), state=state, em_force_N=em_force_N)

    # ------------------------------------------------------------------ the procedure
    def modes(self, theta: Mapping[str, float] | None = None, n: int | None = None, state: str = "power_off",
              *, certify: bool = False) -> ModalResult:
        """Solve the FE model's lowest modes at joint parameters ``theta``.

        Parameters
        ----------
        theta : dict of str -> float, optional
            Joint parameters in N/m^3 to set (others: see :meth:`theta`).
        n : int, optional
            Number of modes (default ``solver.n_modes``).
        state : str
            The state the result is labelled with; when :meth:`identify` ran on it in this study, its
            identified parameters are the starting values.  The rig model itself does not depend on
            the state (the effects of ``effects:`` act in :meth:`diagnose` only).
        certify : bool
            Also count the modes below the highest solved one (Sturm check, one more factorisation).

        Returns
        -------
        ModalResult

        Notes
        -----
        Calls :func:`jointid.identification.polish.solve_point`, the solve of rules ``modal`` and
        ``verify``: :func:`jointid.fe.model.base_coefficients` turns ``theta`` into the term
        coefficients (see :class:`ModalResult`) and :func:`jointid.fe.modal.solve_model` runs
        shift-invert Lanczos on them.
        """
        from jointid.fe.model import base_coefficients
        from jointid.geometry.points import dof_labels
        from jointid.identification.polish import solve_point

        model, values = self.model(), self.theta(state, theta)
        spec = self._settings.model
        freqs, shapes, desc, modes = solve_point(spec, model, values, n_modes=n, certify=certify)
        kc, mc = base_coefficients(spec, model, values)
        return ModalResult(state=state, theta=values, freqs_Hz=np.asarray(freqs), shapes=np.asarray(shapes),
                           labels=tuple(dof_labels(self.points())), phi=modes.phi, energy=desc,
                           k_coefficients=kc, m_coefficients=mc, sturm=modes.sturm)

    def compare(self, dataset: DatasetLike, theta: Mapping[str, float] | None = None, state: str | None = None,
                *, n: int | None = None) -> pd.DataFrame:
        """The model against a measured dataset, mode by mode.

        Parameters
        ----------
        dataset : folder, UFF file or Dataset
            See :meth:`dataset`.
        theta : dict, optional
            Joint parameters (N/m^3) of the model; default per state as in :meth:`modes`.
        state : str, optional
            One state of the dataset (default: all of them, one block each).
        n : int, optional
            Model modes solved (default ``solver.n_modes``).

        Returns
        -------
        DataFrame
            :func:`jointid.correlate.pairing.frequency_errors` per state: ``state, mode,
            freq_meas_Hz, freq_model_Hz, error_pct`` (``100 (model - measured) / measured``),
            ``model_mode, mac, status, description``.  Measured modes are paired by MAC where the
            dataset has shapes (``mac`` filled), else by the order-preserving frequency assignment
            (``mac`` NaN) in which, as in rules ``identify`` and ``verify``, leaving a mode the test
            would clearly have seen unpaired costs its misfit; ``status`` lists unpaired measured modes
            and model modes in the band no measured mode took.
            :func:`jointid.correlate.pairing.error_summary` summarises it.
        """
        from jointid.correlate.pairing import frequency_errors

        frames, min_freq = [], float(self._settings.model.solver.min_freq_Hz)
        for d in self.states(dataset, [state] if state else None):
            m = self.modes(theta, n, state=d.name)
            pairs = measured.pairing(d, m, min_freq)
            frames.append(frequency_errors(d.name, d.f_meas, m.freqs_Hz, pairs, m.descriptions))
        return pd.concat(frames, ignore_index=True)

    def identify(self, dataset: DatasetLike, state: str = "power_off", *,
                 theta0: Mapping[str, float] | None = None, max_iter: int = 8,
                 log: Callable[[str], None] | None = None) -> Identification:
        """Fit the joint parameters of ``joints.parameters`` to one state's measured modes.

        This is the workflow's *FE polish* (:func:`jointid.identification.polish.polish_on_model`,
        called by rule ``identify``): Gauss-Newton on log10 of the parameters with exact modal
        sensitivities, each iterate solved by a reduced solver certified against the full model.
        It is a local search from ``theta0``: the method first runs the DOE, the response
        surfaces and a multistart on them (rules ``doe`` ... ``identify``; :meth:`run_method`),
        which this method leaves out.  Start it near the answer, or from the surface optimum of
        :meth:`run_method` (``identifications[state].surface_optimum``).

        Parameters
        ----------
        dataset : folder, UFF file or Dataset
            The measured modes (:meth:`dataset`).
        state : str
            The state to fit.
        theta0 : dict, optional
            Start, N/m^3 (default: :meth:`theta` of the configuration, the geometric mean of the
            bounds).
        max_iter : int
            Gauss-Newton iterations at most.
        log : callable, optional
            Receives one line per iterate (default: silent).

        Returns
        -------
        Identification
            Also remembered for ``state``: later :meth:`modes` and :meth:`compare` of that state
            start from it.

        Notes
        -----
        The measured state is read as the diagnosis reads it (:meth:`states`).  Its modes are paired
        with the model's at ``theta0`` by MAC where the dataset has shapes (then followed by MAC),
        else by frequency, re-paired at every iterate.  The frequency uncertainty is the dataset's
        ``frequency_uncertainty_pct``, else ``identify.frequency_uncertainty_pct``.  As in rule
        ``identify``, model modes the test would clearly have seen (the dataset's ``test_setup``,
        ``identify.visible_threshold``) and no measured mode takes count as misfits.  Unlike it, the
        states are fitted one by one (no pairing shared by the states, ``identify.pairing``) and
        without mesh extrapolation (``mesh.extrapolate_edges``).
        """
        from jointid.correlate.pairing import PairedBy
        from jointid.identification.polish import PolishFit, polish_on_model

        names = self._settings.model.joints.names
        (d,) = self.states(dataset, [state])
        start = self.modes({**self.theta(), **(theta0 or {})}, state="start")
        meas_shapes = d.pairing_shapes
        pairing = measured.pairing(d, start, float(self._settings.model.solver.min_freq_Hz))
        if len(pairing.unpaired_measured):
            raise DataError(f"measured {state} mode(s) {[i + 1 for i in pairing.unpaired_measured]} pair with "
                            "no model mode at the start — give theta0 nearer the answer, or raise solver.n_modes")
        joints = self._settings.model.joints
        weights = self._study.weights
        weights = np.ones(len(d.f_meas)) if not weights else np.asarray(weights, float)
        weights = weights * (d.noise_rms() / d.mode_sigma()) ** 2  # each mode in units of its own uncertainty
        fit = PolishFit(d.f_meas, start.shapes[:, pairing.model_index], joints.lower_N_per_m3, joints.upper_N_per_m3,
                        weights=weights, sigma_rel=d.noise_rms(),
                        repair=meas_shapes is None, rule=d.rule,
                        shapes=None if meas_shapes is None else d.shapes, shape_sigma_rel=d.shape_sigma_rel)
        polish = polish_on_model(self._settings.model, self.model(), names, np.array([start.theta[k] for k in names]),
                                 fit, max_iter=max_iter, log=log or _quiet)
        result = measured.identification(state, names, start.theta, d.f_meas, polish,
                                         PairedBy.FREQUENCY if meas_shapes is None else PairedBy.MAC,
                                         joints.fixed_N_per_m3)
        self._identified[state] = result
        self._found.pop(state, None)
        return result

    def run_method(self, *, log: Callable[[str], None] | None = None) -> MethodResult:
        """Run the paper's method on the configured states and datasets: DOE -> response surfaces (with
        ``doe.zoom``, a second DOE around the first optima) -> multistart and FE polish -> FE verification ->
        Tables 2-3, as ``snakemake -j2`` does up to ``results/tables/``.

        It calls :func:`jointid.stages.method.run_method`: the stage functions of the rules, with the options
        each rule gets, each handed what the rule's file would hand it.  With single-threaded BLAS (as the
        workflow's jobs run) its numbers are the workflow's, to the last digit.  ``solver.method: rom`` is
        the workflow's alone.

        Parameters
        ----------
        log : callable, optional
            Receives the stages' progress lines (default: silent).

        Returns
        -------
        MethodResult
            The states' identifications, verifications and tables.  The identified parameters are also
            remembered per state: later :meth:`modes` and :meth:`compare` of that state start from them.
        """
        from jointid.stages.method import MethodOptions, run_method

        with _progress(log or _quiet):
            run = run_method(MethodOptions.of(self._study), self.model())
        for state, rec in run.identifications.items():
            self._found[state] = dict(rec.theta)
            self._identified.pop(state, None)
        return MethodResult(identifications=dict(run.identifications),
                            verified={s: v.table for s, v in run.verified.items()},
                            unpaired={s: v.unpaired for s, v in run.verified.items()},
                            tables=dict(run.tables), surface=run.surface)

    def synthetic_dataset(self, truth: str | os.PathLike | Mapping, folder: str | os.PathLike) -> Dataset:
        """Write a synthetic measured dataset with hidden effects (:mod:`jointid.synthetic.generate`) to
        ``folder`` from a truth file or mapping (``tests/hidden/*.yaml`` are examples), solved on this
        study's model; returns the :class:`jointid.data.dataset.Dataset`."""
        from jointid.config.synthetic import truth_config
        from jointid.config.typed_diagnosis import DiagnosisSettings
        from jointid.synthetic import generate as synth

        if isinstance(truth, Mapping):
            synth.check_truth(dict(truth))
            truth = dict(truth)
        else:
            truth = synth.load_truth(truth)
        settings = DiagnosisSettings.from_config(truth_config(truth, self._study.config))
        return synth.write_synthetic(truth, settings, folder, model=self.model())

    def diagnose(self, dataset: DatasetLike, *, candidates: Sequence[str] | None = None,
                 states: Sequence[str] | None = None, effects: Mapping | None = None,
                 out_dir: str | os.PathLike | None = None,
                 log: Callable[[str], None] | None = None) -> DiagnosisResult:
        """Which physical effect the model lacks (docs/effects.md): compare, score every library
        effect, refit the leading ones, verdict.

        Parameters
        ----------
        dataset : folder, UFF file or Dataset
            The measured states (:meth:`dataset`); two force levels (``em_force_N`` in its
            conditions) separate state-dependent effects.
        candidates : sequence of str, optional
            Library effects to test (default: every effect not enabled; see
            :func:`jointid.diagnosis.effects.effect_table`).
        states : sequence of str, optional
            States of the dataset to use (default: all).
        effects : mapping, optional
            Effects enabled in the model (default: the ``effects`` config section).
        out_dir : path, optional
            Also write the diagnosis files of the workflow (``ranking.csv``, ``ladder.csv``,
            ``index.html`` ...) there.
        log : callable, optional
            Progress lines (default: silent).

        Returns
        -------
        DiagnosisResult

        Notes
        -----
        Calls :func:`jointid.diagnosis.loop.diagnose`, the loop of rule ``diagnose``, on the
        diagnosis system of this study's model (built once); its reduced solver is kept and reused
        by the next diagnosis of this study (its subspace only grows).
        """
        from jointid.diagnosis.loop import diagnose

        ds = self._as_dataset(dataset)
        data = self.states(ds, states)
        res = diagnose(self.system(), self._study.diagnosis, data, effects=None if effects is None else dict(effects),
                       candidates=None if candidates is None else list(candidates), solver=self._solver,
                       log=log or _quiet)
        self._solver = res.solver
        if out_dir is not None:
            measured.write_diagnosis(res, out_dir, ds.name, self._study.config_hash)
        return DiagnosisResult(verdict=res.verdict, explained_by=res.explained_by, ranking=res.ranking,
                               ladder=res.ladder, compare=res.compare, timing_s=res.timing_s, raw=res)

    # ------------------------------------------------------------------ helpers
    def system(self):
        """The diagnosis system of the model (:func:`jointid.diagnosis.terms.build_system`: joint
        layers split per carriage), built once."""
        if self._system is None:
            from jointid.diagnosis.terms import build_system

            self._system = build_system(self.model(), self._settings.model)
        return self._system

    def states(self, dataset: DatasetLike, states: Sequence[str] | None = None) -> list:
        """The measured states of ``dataset`` as the diagnosis and :meth:`identify` use them
        (:func:`jointid.diagnosis.variants.dataset_states`): per state its frequencies ``f_meas``
        (Hz), its shapes at the measuring points ``(n_labels, n)`` or None, the motor force, the
        relative frequency uncertainty ``sigma_rel`` and the test's observability rule.

        Raises
        ------
        jointid.errors.DataError
            A state not in the dataset, or a measured mode below ``solver.min_freq_Hz``.
        """
        from jointid.diagnosis.variants import dataset_states

        return dataset_states(self._as_dataset(dataset), self.system(), self._study.diagnosis,
                              list(states) if states else None)

    def _as_dataset(self, dataset: DatasetLike) -> Dataset:
        from jointid.data.dataset import Dataset

        return dataset if isinstance(dataset, Dataset) else self.dataset(Path(dataset))

    def __repr__(self) -> str:
        names = ", ".join(self._settings.model.joints.names)
        built = f"{self._model.n_dofs} DOFs" if self._model is not None else "model not built yet"
        return f"Study({self._settings.model.mesh.element} mesh, {built}; identified: {names})"
