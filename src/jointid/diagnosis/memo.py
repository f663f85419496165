"""Fits remembered from one diagnosis run to the next on the same model (``diagnosis.reuse_subspace``).

The loop of docs/effects.md asks many of the last run's questions again: enabling the effect it
suggested, the next run calibrates the baseline exactly as before, and several of its fits start
where the last run's did (the baseline calibrations, a candidate continued from the same optimum
with a new effect at its null ...).  :class:`FitMemo` records each fit by a digest of everything it
depends on:

* the code of the package (any change to it forgets every record),
* the measured states (frequencies, shapes, uncertainties, the observability rule),
* the configuration the fits read (all sections but ``diagnosis``, ``dataset`` and ``effects``; the
  effects of a variant are part of the variant),
* the variant (joint parameters and bounds, each effect with its values, options and free parameters),
* the start vector (to :data:`START_RESOLUTION`), the pairing it starts from, the loop count and the
  solver's mode count and tolerance.

A fit asked again with the same digest is not searched again: the Diagnoser evaluates the variant
at the recorded optimum with the recorded pairing and misfit set, checked in the full space as
every answer is (:meth:`jointid.diagnosis.fitting.Diagnoser.fit`; a check that passed on the kept
basis vectors holds on them still, :mod:`jointid.fe.warmstart`), and certifies it there when asked
(Sturm counts at the same point are themselves kept, :mod:`jointid.fe.warmstart`).  The answer equals
the search's to the solver tolerance; the model is the one the records were made on (the kept file's
fingerprint).  A run from clean has no records and stays bit-reproducible.
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

from jointid.version import code_digest

MAX_RECORDS = 4000
"""Most records kept (the newest)."""
START_RESOLUTION = 1e-9
"""Starts closer than this in every component (log parameters, effect test variables) are one start:
a start computed from certified answers (a score-test estimate) differs from run to run in its last
digits, as the answers do (the solver tolerance is 1e-6)."""


def _feed(h, obj) -> None:
    """Feed a canonical, exact serialisation of ``obj`` into the hash ``h``."""
    if obj is None or isinstance(obj, (bool, str, int)):
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, float):
        h.update(f"f:{obj.hex()};".encode())
    elif isinstance(obj, np.generic):
        _feed(h, obj.item())
    elif isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"a:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes() if a.dtype != object else repr(a.tolist()).encode())
    elif isinstance(obj, dict):
        h.update(f"d{len(obj)}(".encode())
        for k in obj:  # insertion order: the same config file gives the same order
            _feed(h, k)
            _feed(h, obj[k])
        h.update(b")")
    elif isinstance(obj, (list, tuple)):
        h.update(f"l{len(obj)}(".encode())
        for v in obj:
            _feed(h, v)
        h.update(b")")
    elif dataclasses.is_dataclass(obj):
        h.update(f"dc:{type(obj).__name__}(".encode())
        for fld in dataclasses.fields(obj):
            _feed(h, fld.name)
            _feed(h, getattr(obj, fld.name))
        h.update(b")")
    else:  # an object of unknown state: its type name and repr (an address in it only costs a miss)
        h.update(f"o:{type(obj).__module__}.{type(obj).__qualname__}:{obj!r};".encode())


def variant_signature(variant) -> list:
    """What defines a variant's fit: joint parameters, bounds, fixed values and each effect (its
    options, free parameters and the values of the others; a free parameter's start value is in ``x0``)."""
    return [variant.joint_names, variant.theta_fixed, variant.lower, variant.upper,
            [(s.effect.name, {k: v for k, v in s.values.items() if k not in s.free}, s.options, list(s.free))
             for s in variant.effects]]


class FitMemo:
    """Records of fits by digest: the optimum, the pairing and the misfit set of each state."""

    def __init__(self, records: dict | None = None):
        self.records: dict = dict(records or {})
        self.hits = self.misses = 0

    @staticmethod
    def context(settings, data: list, n_modes: int, tol: float, mac_threshold: float) -> str:
        """Digest of what every fit of one Diagnoser depends on besides the variant and the start
        (``settings``: its :class:`jointid.config.typed_diagnosis.DiagnosisSettings`)."""
        h = hashlib.sha256(code_digest().encode())
        _feed(h, settings.fingerprint)  # every section but diagnosis, dataset and effects
        _feed(h, list(data))
        _feed(h, settings.shape_residuals)  # shape rows in the fits
        _feed(h, settings.mesh_error)  # the mesh's correction in the fits
        _feed(h, [int(n_modes), float(tol), float(mac_threshold)])
        return h.hexdigest()

    @staticmethod
    def key(context: str, variant, x0: np.ndarray, index, max_loops: int) -> str:
        """Digest of one fit: the context, the variant, the start and its pairing, the loop count."""
        h = hashlib.sha256(context.encode())
        _feed(h, variant_signature(variant))
        _feed(h, np.round(np.asarray(x0, float) / START_RESOLUTION).astype(np.int64))
        _feed(h, None if index is None else [np.asarray(i, np.int64) for i in index])
        _feed(h, int(max_loops))
        return h.hexdigest()

    @staticmethod
    def value_key(context: str, name: str, *parts) -> str:
        """Digest of a value computed once per context (e.g. the mesh errors at one parameter point)."""
        h = hashlib.sha256(context.encode())
        _feed(h, name)
        for p in parts:
            _feed(h, p)
        return "value:" + h.hexdigest()

    def get_value(self, key: str):
        """A value recorded with :meth:`put_value` (None when there is none)."""
        return self.records.get(key)

    def put_value(self, key: str, value) -> None:
        """Record a JSON-ready ``value`` under ``key`` (kept with the fits, :mod:`jointid.fe.warmstart`)."""
        self.records.pop(key, None)
        self.records[key] = value

    def get(self, key: str) -> dict | None:
        rec = self.records.get(key)
        if rec is None:
            self.misses += 1
            return None
        self.hits += 1
        return {"x": np.array([float.fromhex(v) for v in rec["x"]]),
                "index": [np.asarray(i, int) for i in rec["index"]],
                "misfits": [(np.asarray(c, int), np.array([float.fromhex(v) for v in t]))
                            for c, t in rec["misfits"]]}

    def put(self, key: str, ev) -> None:
        """Record the final evaluation ``ev`` (:class:`jointid.diagnosis.results.Evaluation`) of a fit."""
        self.records.pop(key, None)
        self.records[key] = {"x": [float(v).hex() for v in ev.x],
                             "index": [[int(i) for i in ix] for ix in ev.index],
                             "misfits": [[[int(c) for c in m[0]], [float(t).hex() for t in m[1]]]
                                         for m in ev.misfits]}
        while len(self.records) > MAX_RECORDS:
            self.records.pop(next(iter(self.records)))
