"""The observability rule of the identification: a mode the test would clearly have seen is never skipped free.

The measured modes are paired with model modes (by MAC, or by an order-preserving frequency
assignment when only frequencies are measured).  A model mode inside the test band that no measured
mode is paired with, but that the test would clearly have seen
(:func:`jointid.correlate.observability.clearly_visible`), is a **misfit** of the model: it enters
the objective as a residual ``(f_u - f_near) / f_near``, its distance to the nearest measured mode
or band edge (a mode near a measured one may have merged with it in the test; one just inside the
band edge would be unseen just outside it; one far from both is a peak the test does not show), and the frequency-only pairing pays that residual, squared, for
leaving it unpaired.  The same rule serves the surfaces, the FE polish and the verification.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointid.config.typed import TestSetup
from jointid.correlate.observability import (VISIBLE_THRESHOLD, MeasurementSetup, clearly_visible,
                                             misfit_target, test_band, visibility)
from jointid.correlate.pairing import pair_by_frequency

__all__ = ["VisibilityRule", "dataset_rule", "misfit_table"]


@dataclass(frozen=True)
class VisibilityRule:
    """Which model modes the test must account for.

    Attributes
    ----------
    setup : MeasurementSetup
        Excitation and response DOFs of the test.
    labels : list of str
        DOF label of each row of the model shapes given to the methods (``"<point>:<direction>"``).
    band_Hz : (float, float)
        The test's band; modes outside it are never counted.
    threshold : float
        Clearly visible: at least this share of the weakest paired mode's visibility.
    """

    setup: MeasurementSetup
    labels: tuple
    band_Hz: tuple
    threshold: float = VISIBLE_THRESHOLD

    def visibility(self, shapes: np.ndarray, freqs_Hz: np.ndarray) -> np.ndarray:
        """Visibility (m/N, at a damping ratio of 0.03) of each mode; shapes ``(n_labels, n)``."""
        return visibility(shapes, freqs_Hz, list(self.labels), self.setup)

    def misfits(self, index, freqs_Hz, vis, f_meas) -> tuple[np.ndarray, np.ndarray]:
        """``(modes, targets)``: the clearly visible modes in the band that ``index`` (the model mode of
        each measured mode) leaves unpaired, and what each is scored against (Hz): the nearest measured
        frequency or band edge (:func:`jointid.correlate.observability.misfit_target`)."""
        freqs_Hz = np.asarray(freqs_Hz, float)
        index = np.asarray(index, int)
        seen = clearly_visible(vis, index, self.threshold)
        inside = (freqs_Hz >= self.band_Hz[0]) & (freqs_Hz <= self.band_Hz[1])
        taken = np.zeros(freqs_Hz.size, bool)
        taken[index[index >= 0]] = True
        cols = np.flatnonzero(seen & inside & ~taken)
        return cols, misfit_target(freqs_Hz[cols], f_meas, self.band_Hz) if cols.size else np.zeros(0)

    def skip_costs(self, index, freqs_Hz, vis, f_meas) -> np.ndarray:
        """Cost of leaving each mode unpaired in the frequency pairing: the squared log distance to the
        nearest measured mode or band edge for a clearly visible mode in the band (visibility judged against the
        modes ``index`` pairs), else 0."""
        freqs_Hz = np.asarray(freqs_Hz, float)
        index = np.asarray(index, int)
        seen = clearly_visible(vis, index, self.threshold)
        inside = (freqs_Hz >= self.band_Hz[0]) & (freqs_Hz <= self.band_Hz[1])
        with np.errstate(divide="ignore", invalid="ignore"):  # 0-Hz rigid-body modes: outside the band
            cost = np.log(freqs_Hz / misfit_target(freqs_Hz, f_meas, self.band_Hz)) ** 2
        return np.where(seen & inside, cost, 0.0)

    def pair_by_frequency(self, f_meas, freqs_Hz, vis, candidates: np.ndarray, max_rounds: int = 6) -> np.ndarray:
        """Order-preserving frequency pairing among the model modes ``candidates`` in which leaving a
        clearly visible mode unpaired costs its misfit; the model mode of each measured mode.

        Visibility is judged against the weakest paired mode, so the pairing and the costs are
        settled in turn, from the free pairing, until the pairing repeats (at most ``max_rounds``).
        """
        f_meas = np.asarray(f_meas, float)
        freqs_Hz = np.asarray(freqs_Hz, float)
        candidates = np.asarray(candidates, int)
        index = candidates[pair_by_frequency(f_meas, freqs_Hz[candidates])]
        seen = set()
        for _ in range(max_rounds):
            skip = self.skip_costs(index, freqs_Hz, vis, f_meas)[candidates]
            new = candidates[pair_by_frequency(f_meas, freqs_Hz[candidates], skip_cost=skip)]
            if np.array_equal(new, index) or tuple(new) in seen:
                return new
            seen.add(tuple(index))
            index = new
        return index


def misfit_table(rule: VisibilityRule, index, freqs_Hz, vis, f_meas, descriptions=None) -> list[dict]:
    """The unpaired, clearly visible modes as records for params.json and the tables.

    Each: ``model_mode`` (1-based), ``freq_Hz``, ``target_Hz``, ``misfit_pct`` (signed,
    model minus the target: nearest measured mode or band edge), ``visibility_rel`` (to the weakest paired mode) and, if given,
    ``description``.
    """
    cols, targets = rule.misfits(index, freqs_Hz, vis, f_meas)
    index = np.asarray(index, int)
    weakest = float(np.min(np.asarray(vis)[index[index >= 0]])) if np.any(index >= 0) else float("nan")
    out = []
    for j, t in zip(cols, targets):
        rec = {"model_mode": int(j) + 1, "freq_Hz": float(freqs_Hz[j]), "target_Hz": float(t),
               "misfit_pct": float(100 * (freqs_Hz[j] - t) / t), "visibility_rel": float(vis[j] / weakest)}
        if descriptions is not None:
            rec["description"] = str(descriptions[j])
        out.append(rec)
    return out


def dataset_rule(ds, state: str, labels: list, point_names: list, shapes, test: TestSetup, where: str):
    """The observability rule of ``state`` of the dataset ``ds`` (None when
    ``test.visible_threshold`` is None).

    The dataset's ``test_setup`` (default ``test``: the hammer at ``test.drive_point`` in x, y and z, the
    responses where ``shapes`` — the state's measured shapes at ``labels``, or None — are finite, else
    every point in x, y and z), the test band (:func:`jointid.correlate.observability.test_band`, default
    ``test.band_Hz``) and the threshold.  ``where`` names the conditions file in the setup's note.
    """
    if test.visible_threshold is None:
        return None
    measured = None
    if shapes is not None:
        measured = [lab for lab, ok in zip(labels, np.isfinite(shapes).any(axis=1)) if ok]
    spec = ds.conditions.get("test_setup")
    setup = MeasurementSetup.from_spec(spec, list(point_names), [f"{test.drive_point}:{d}" for d in "xyz"],
                                       measured_labels=measured, where=where)
    band = test_band(spec, test.band_Hz, ds.freqs(state))
    return VisibilityRule(setup, tuple(labels), band, float(test.visible_threshold))
