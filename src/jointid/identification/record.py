"""The identification of one state as rule ``identify`` writes it: ``results/identify/<state>/params.json``.

:class:`IdentificationRecord` is that file as a frozen dataclass.
:meth:`IdentificationRecord.to_json` gives the file's content and :meth:`IdentificationRecord.from_json` reads it back.
Every reader of ``params.json`` goes through it, not through its keys.

The JSON text stays that of the earlier dict, byte for byte.
Floats of a parameter interval (:class:`Interval`) are written at full precision, as numpy scalars.
Every other float is written at the 12 significant digits of :func:`jointid.io.write_json`.
A record read back therefore writes the same bytes again.

Records the identification takes from other modules stay dicts, in their owners' format:
``joint_pairing`` (:func:`jointid.identification.updating.identify_states_jointly`),
``edge_extrapolation`` (:func:`jointid.identification.polish.extrapolated_polish`),
``model_error`` (:meth:`jointid.identification.model_error.ModelError.record`),
``joint_damping`` (:func:`jointid.identification.joint_damping.stage_record`) and the certificate of
the polish (:meth:`jointid.fe.certificate.Certificate.to_record`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from jointid import io
from jointid.correlate.pairing import PairedBy
from jointid.identification import ties

__all__ = ["FePolish", "IdentificationRecord", "Interval", "Observability", "PairedBy", "PolishedOn",
           "SurfaceStage", "TieChoice", "TieRule", "floats"]


class SurfaceStage(str, Enum):
    """The response surfaces the multistart ran on (``surface_stage``)."""

    GLOBAL = "global"
    """The surfaces of the DOE over the configured bounds."""
    ZOOM = "zoom"
    """The surfaces of the zoomed DOE around the first optimum."""


class PolishedOn(str, Enum):
    """The model the FE polish solved (``fe_polish.on``)."""

    FE = "fe"
    """The full FE model."""
    ROM = "rom"
    """The verified reduced-order model."""


class TieChoice(Enum):
    """The rule that chose among exactly tied pairings (the start of ``tie_rule.rule``)."""

    NO_TIE = ties.NO_TIE
    """No tie: the least cost chose."""
    RESOLVABILITY = ties.RESOLVABILITY
    """The one pairing whose unpaired visible modes could all hide in a measured peak."""
    NEAREST = ties.NEAREST
    """The nearest partners, a fallback (the text says why)."""


def floats(values) -> tuple[float, ...]:
    """``values`` as a tuple of Python floats (written at 12 significant digits, as an array's)."""
    return tuple(np.asarray(values, float).tolist())


def _optional(cls, doc):
    """``cls.from_json(doc)``, or None for a null ``doc``."""
    return None if doc is None else cls.from_json(doc)


def _full(x):
    """A float of an interval as the file holds it: a numpy scalar (full precision); None stays None."""
    return None if x is None else np.float64(x)


@dataclass(frozen=True)
class Interval:
    """A value and its 95 % interval, in the unit its name gives (``parameters``: N/m^3)."""

    value: float
    ci95_low: float | None = None
    ci95_high: float | None = None

    def to_json(self) -> dict:
        """``{"value", "ci95_low", "ci95_high"}`` at full precision."""
        return {"value": _full(self.value), "ci95_low": _full(self.ci95_low), "ci95_high": _full(self.ci95_high)}

    @classmethod
    def from_json(cls, doc: dict) -> "Interval":
        """The interval of a JSON record (absent bounds: None)."""
        return cls(doc["value"], doc.get("ci95_low"), doc.get("ci95_high"))


@dataclass(frozen=True)
class Observability:
    """The test setup the visibility rule judged with (``observability``)."""

    excitation: tuple[str, ...]
    response: tuple[str, ...]
    note: str
    band_Hz: tuple[float, float]
    threshold: float

    @classmethod
    def of(cls, rule) -> "Observability":
        """The record of a :class:`jointid.identification.visibility.VisibilityRule`."""
        return cls(tuple(rule.setup.excitation), tuple(rule.setup.response), rule.setup.note,
                   tuple(rule.band_Hz), rule.threshold)

    def rule(self, labels):
        """The :class:`jointid.identification.visibility.VisibilityRule` at the model's probe ``labels``."""
        from jointid.correlate.observability import MeasurementSetup
        from jointid.identification.visibility import VisibilityRule

        setup = MeasurementSetup(self.excitation, self.response, self.note)
        return VisibilityRule(setup, tuple(labels), tuple(self.band_Hz), float(self.threshold))

    def to_json(self) -> dict:
        return {"excitation": list(self.excitation), "response": list(self.response), "note": self.note,
                "band_Hz": list(self.band_Hz), "threshold": self.threshold}

    @classmethod
    def from_json(cls, doc: dict) -> "Observability":
        return cls(tuple(doc["excitation"]), tuple(doc["response"]), doc.get("note", ""), tuple(doc["band_Hz"]),
                   doc["threshold"])


@dataclass(frozen=True)
class TieRule:
    """Which rule chose among exactly tied pairings (``tie_rule``, :func:`jointid.identification.updating.tie_record`).

    ``rule``: the rule in words; ``tied``: per tied pairing its ``pairing``, ``resolvable``,
    ``unpaired_visible`` and ``damping_ratio_needed``; ``damping_ratio_source``: per state, where the
    damping ratios came from.
    """

    rule: str
    tied: tuple[dict, ...] = ()
    damping_ratio_source: dict | None = None

    @property
    def choice(self) -> TieChoice | None:
        """The rule as a :class:`TieChoice` (None: a text none starts with)."""
        return next((c for c in TieChoice if self.rule.startswith(c.value)), None)

    def tied_pairing(self, columns) -> dict | None:
        """The record of the tied pairing of surface ``columns``, or None."""
        return next((t for t in self.tied if t["pairing"] == columns), None)

    def to_json(self) -> dict:
        out = {"rule": self.rule, "tied": list(self.tied)}
        return out if self.damping_ratio_source is None else {**out, "damping_ratio_source": self.damping_ratio_source}

    @classmethod
    def from_json(cls, doc: dict) -> "TieRule":
        return cls(doc["rule"], tuple(doc.get("tied", ())), doc.get("damping_ratio_source"))


_SHAPE_KEYS = ("shape_chi2", "shape_dof", "shape_c_hat", "shape_uncertainty", "cluster_factor")


@dataclass(frozen=True)
class FePolish:
    """The FE polish of the surface optimum (``fe_polish``, :func:`jointid.identification.polish.fe_polish`).

    The frequencies are in Hz; ``chi2`` is the frequency block's at the stated uncertainty, with ``dof``
    degrees of freedom.  The ``shape_*`` fields and ``cluster_factor`` are None unless measured
    shapes were fitted (:mod:`jointid.identification.polish_shapes`).
    """

    on: PolishedOn
    unpaired_in_band_Hz: tuple[float, ...]
    unpaired_visible: tuple[dict, ...]
    chi2: float
    dof: int
    interval_scale: float
    iterations: int
    cost_history: tuple[float, ...]
    f_fe_Hz: tuple[float, ...]
    mac: tuple[float, ...]
    certificate: dict | None = None
    shape_chi2: float | None = None
    shape_dof: int | None = None
    shape_c_hat: float | None = None
    shape_uncertainty: float | None = None
    cluster_factor: float | None = None

    @classmethod
    def of(cls, polish: dict, on: PolishedOn) -> "FePolish":
        """The record of a polish dict (:func:`jointid.identification.polish.fe_polish`, with its
        ``interval_scale``) solved on model ``on``."""
        cert = polish.get("certificate")
        return cls(on, tuple(polish["unpaired_in_band_Hz"]), tuple(polish["unpaired_visible"]), polish["chi2"],
                   polish["dof"], polish["interval_scale"], polish["iterations"], tuple(polish["cost_history"]),
                   floats(polish["f_fe"]), floats(polish["mac"]), cert.to_record() if cert else None,
                   **{k: polish[k] for k in _SHAPE_KEYS if k in polish})

    def to_json(self) -> dict:
        out = {"on": self.on.value, "unpaired_in_band_Hz": list(self.unpaired_in_band_Hz),
               "unpaired_visible": list(self.unpaired_visible), "chi2": self.chi2, "dof": self.dof,
               "interval_scale": self.interval_scale, "iterations": self.iterations,
               "cost_history": list(self.cost_history), "f_fe_Hz": list(self.f_fe_Hz), "mac": list(self.mac),
               "certificate": self.certificate}
        return out | {k: getattr(self, k) for k in _SHAPE_KEYS if getattr(self, k) is not None}

    @classmethod
    def from_json(cls, doc: dict) -> "FePolish":
        return cls(PolishedOn(doc["on"]), tuple(doc["unpaired_in_band_Hz"]), tuple(doc["unpaired_visible"]),
                   doc["chi2"], doc["dof"], doc["interval_scale"], doc["iterations"], tuple(doc["cost_history"]),
                   tuple(doc["f_fe_Hz"]), tuple(doc["mac"]), doc.get("certificate"),
                   **{k: doc[k] for k in _SHAPE_KEYS if k in doc})


def _intervals(doc: dict | None) -> dict[str, Interval]:
    return {n: Interval.from_json(v) for n, v in (doc or {}).items()}


@dataclass(frozen=True)
class IdentificationRecord:
    """One state's identification: the content of ``results/identify/<state>/params.json``.

    Frequencies in Hz, ``parameters`` and ``surface_optimum`` in N/m^3 (the names carry the unit),
    ``per_carriage`` in N/um per carriage, ``residual_pct`` and ``frequency_uncertainty_pct`` in %.
    ``pairing_columns`` are the surface model's columns paired with the measured modes, in their
    order; ``pairing_tracked_mode`` the tracked modes they are.  A document without some part (a
    test's hand-written one) reads with that part empty or None.
    """

    parameters: dict[str, Interval]
    state: str = ""
    surface_optimum: dict[str, float] | None = None
    surface_stage: SurfaceStage | None = None
    surface_box: dict[str, tuple[float, float]] | None = None
    fe_polish: FePolish | None = None
    edge_extrapolation: dict | None = None
    per_carriage: dict[str, Interval] | None = None
    x_coded: tuple[float, ...] = ()
    pairing_tracked_mode: tuple[int, ...] = ()
    pairing_columns: tuple[int, ...] = ()
    paired_by: PairedBy | None = None
    joint_pairing: dict | None = None
    f_meas_Hz: tuple[float, ...] = ()
    f_surface_Hz: tuple[float, ...] = ()
    residual_pct: tuple[float, ...] = ()
    cost: float | None = None
    condition_number: float | None = None
    weak_combination: str | None = None
    on_bound: tuple[str, ...] = ()
    n_starts_agreeing: int | None = None
    warnings: tuple[str, ...] = ()
    frequency_uncertainty_pct: float | None = None
    model_error: dict | None = None
    tie_rule: TieRule | None = None
    observability: Observability | None = None
    joint_damping: dict | None = None

    @property
    def names(self) -> list[str]:
        """The identified parameters, in the surface model's order."""
        return list(self.parameters)

    @property
    def theta(self) -> dict[str, float]:
        """The identified parameters' values, N/m^3."""
        return {n: v.value for n, v in self.parameters.items()}

    @property
    def theta_low(self) -> dict[str, float]:
        """The low ends of the 95 % intervals, N/m^3."""
        return {n: v.ci95_low for n, v in self.parameters.items()}

    @property
    def theta_high(self) -> dict[str, float]:
        """The high ends of the 95 % intervals, N/m^3."""
        return {n: v.ci95_high for n, v in self.parameters.items()}

    def interval(self, name: str) -> Interval:
        """The value and 95 % interval of parameter ``name``."""
        return self.parameters[name]

    @property
    def correction_record(self) -> dict | None:
        """The mesh-extrapolation factors of the last polish (a :class:`jointid.fe.extrapolate.FrequencyCorrection`
        record), or None."""
        return (self.edge_extrapolation or {}).get("correction")

    @property
    def pairing_candidates(self) -> list[dict]:
        """The pairings the joint pairing of frequency-only states tried (empty without one)."""
        return list((self.joint_pairing or {}).get("candidates") or [])

    def to_json(self) -> dict:
        """The ``params.json`` content (:func:`jointid.io.write_json` writes it)."""
        out = {"state": self.state, "parameters": {n: v.to_json() for n, v in self.parameters.items()},
               "surface_optimum": self.surface_optimum, "surface_stage": _value(self.surface_stage),
               "surface_box": None if self.surface_box is None else {n: list(b) for n, b in self.surface_box.items()},
               "fe_polish": _json(self.fe_polish), "edge_extrapolation": self.edge_extrapolation,
               "per_carriage": None if self.per_carriage is None else {
                   n: v.to_json() for n, v in self.per_carriage.items()},
               "x_coded": list(self.x_coded), "pairing_tracked_mode": list(self.pairing_tracked_mode),
               "pairing_columns": list(self.pairing_columns), "paired_by": _value(self.paired_by),
               "joint_pairing": self.joint_pairing, "f_meas_Hz": list(self.f_meas_Hz),
               "f_surface_Hz": list(self.f_surface_Hz), "residual_pct": list(self.residual_pct), "cost": self.cost,
               "condition_number": self.condition_number, "weak_combination": self.weak_combination,
               "on_bound": list(self.on_bound), "n_starts_agreeing": self.n_starts_agreeing,
               "warnings": list(self.warnings), "frequency_uncertainty_pct": self.frequency_uncertainty_pct,
               "model_error": self.model_error, "tie_rule": _json(self.tie_rule),
               "observability": _json(self.observability)}
        return out if self.joint_damping is None else {**out, "joint_damping": self.joint_damping}

    @classmethod
    def from_json(cls, doc: dict) -> "IdentificationRecord":
        """The record of a ``params.json`` content."""
        box = doc.get("surface_box")
        stage = doc.get("surface_stage")
        return cls(
            parameters=_intervals(doc["parameters"]), state=doc.get("state", ""),
            surface_optimum=doc.get("surface_optimum"), surface_stage=None if stage is None else SurfaceStage(stage),
            surface_box=None if box is None else {n: tuple(b) for n, b in box.items()},
            fe_polish=_optional(FePolish, doc.get("fe_polish")), edge_extrapolation=doc.get("edge_extrapolation"),
            per_carriage=None if doc.get("per_carriage") is None else _intervals(doc["per_carriage"]),
            x_coded=tuple(doc.get("x_coded", ())), pairing_tracked_mode=tuple(doc.get("pairing_tracked_mode", ())),
            pairing_columns=tuple(doc.get("pairing_columns", ())), paired_by=PairedBy.of(doc),
            joint_pairing=doc.get("joint_pairing"), f_meas_Hz=tuple(doc.get("f_meas_Hz", ())),
            f_surface_Hz=tuple(doc.get("f_surface_Hz", ())), residual_pct=tuple(doc.get("residual_pct", ())),
            cost=doc.get("cost"), condition_number=doc.get("condition_number"),
            weak_combination=doc.get("weak_combination"), on_bound=tuple(doc.get("on_bound", ())),
            n_starts_agreeing=doc.get("n_starts_agreeing"), warnings=tuple(doc.get("warnings", ())),
            frequency_uncertainty_pct=doc.get("frequency_uncertainty_pct"), model_error=doc.get("model_error"),
            tie_rule=_optional(TieRule, doc.get("tie_rule")),
            observability=_optional(Observability, doc.get("observability")), joint_damping=doc.get("joint_damping"))

    @classmethod
    def read(cls, path) -> "IdentificationRecord":
        """The record in the ``params.json`` at ``path``."""
        return cls.from_json(io.read_json(path))

    def write(self, path) -> None:
        """Write the record to ``path`` (``params.json``)."""
        io.write_json(path, self.to_json())


def _value(member):
    return None if member is None else member.value


def _json(part):
    return None if part is None else part.to_json()


def by_state(paths) -> dict[str, IdentificationRecord]:
    """The records of ``params.json`` files, keyed by their folder's name (the state)."""
    return {Path(p).parent.name: IdentificationRecord.read(p) for p in paths}
