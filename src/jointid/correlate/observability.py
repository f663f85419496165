"""How strongly a modal test sees each model mode (observability), and which modes it must have seen.

A hammer test excites the structure at fixed DOFs (point and direction of the hammer) and measures
the response at others (a roving accelerometer).  Mode ``r`` adds to the receptance between response
DOF ``j`` and excitation DOF ``k`` the term ``phi_jr phi_kr / (w_r^2 - w^2 + 2 i zeta_r w_r w)``
(mass-normalised ``phi``).  At its resonance that term peaks at ``|phi_jr phi_kr| / (2 zeta_r w_r^2)``.
Summed over every measured (response, excitation) pair, this is the peak mode ``r`` adds to the
summed FRF magnitude from which a test engineer picks the modes (the sum function of LMS Test.Lab
and its peers): the mode's **visibility**, in m/N.  With one damping ratio for every mode the
*relative* visibility of two modes does not depend on its value.

A model mode is **clearly visible** when its visibility reaches ``threshold`` (default 0.25) times
that of the weakest model mode the pairing already matched with a measured mode: the test saw that
one, so it would have seen a mode that shows at least a quarter as strongly.  A clearly visible
model mode inside the test's band that no measured mode is paired with is a *misfit* of the model,
never a free skip (docs/reconstruction.md, "Observability").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MeasurementSetup", "VISIBLE_THRESHOLD", "clearly_visible", "misfit_target", "nearest_measured", "test_band",
           "visibility"]

VISIBLE_THRESHOLD = 0.25
"""Default: a mode is clearly visible at a quarter of the weakest paired mode's visibility."""
DIRECTIONS = ("x", "y", "z")


@dataclass(frozen=True)
class MeasurementSetup:
    """Where a modal test excited and measured.

    Attributes
    ----------
    excitation : tuple of str
        DOF labels ``"<point>:<direction>"`` of the hammer (fixed tapping points and directions).
    response : tuple of str
        DOF labels of the measured responses (every point and direction the sensor visited).
    note : str
        Where the setup comes from (the dataset's ``test_setup`` or the assumption made).
    """

    excitation: tuple
    response: tuple
    note: str = ""

    @classmethod
    def from_spec(cls, spec: dict | None, points: list[str], default_excitation: list[str], *,
                  measured_labels: list[str] | None = None, where: str = "conditions.yaml") -> "MeasurementSetup":
        """The setup of a dataset's ``test_setup`` block (docs/measurement-format.md), or the default.

        Parameters
        ----------
        spec : dict or None
            ``{"excitation": ["T05:y", ...], "response_points": "all" | [names],
            "response_directions": ["x", "y", "z"], "note": "..."}``; None: not given.
        points : list of str
            The measuring points of the model (their names).
        default_excitation : list of str
            Excitation DOFs assumed when ``spec`` gives none (e.g. the drive point in x, y and z).
        measured_labels : list of str, optional
            DOF labels the dataset's shapes cover; the default response when ``spec`` gives none.
        """
        spec = dict(spec or {})
        excitation = tuple(spec.get("excitation") or default_excitation)
        dirs = tuple(spec.get("response_directions") or DIRECTIONS)
        resp_pts = spec.get("response_points", "all")
        if resp_pts in (None, "all"):
            resp_pts = list(points)
        if "response_points" in spec or "response_directions" in spec or not measured_labels:
            response = tuple(f"{p}:{d}" for p in resp_pts for d in dirs)
        else:
            response = tuple(measured_labels)
        note = str(spec.get("note") or (f"as given in {where}" if spec else
                                         f"not given in {where}; assumed: hammer at {', '.join(excitation)}, "
                                         f"responses at {len(response)} point DOFs"))
        return cls(excitation=excitation, response=response, note=note)


def test_band(spec: dict | None, default_band_Hz, f_meas_Hz, margin: float = 0.02) -> tuple[float, float]:
    """The band in which a test reports every mode it saw (Hz).

    The dataset's ``test_setup.band_Hz`` when given.  Otherwise the default band (``harmonic.band_Hz``)
    capped at the highest measured mode plus ``margin``: a test that lists the first N modes says
    nothing about the modes above its N-th, so a model mode there is not a misfit.
    """
    band = (spec or {}).get("band_Hz")
    if band is not None:
        return float(band[0]), float(band[1])
    lo, hi = (float(b) for b in default_band_Hz)
    f = np.asarray(f_meas_Hz, float)
    if f.size:
        hi = min(hi, float(f.max()) * (1.0 + margin))
    return lo, hi


def visibility(shapes: np.ndarray, freqs_Hz: np.ndarray, labels: list[str], setup: MeasurementSetup,
               zeta: float | np.ndarray = 0.03) -> np.ndarray:
    """Peak that each mode adds to the summed FRF magnitude of the test (m/N).

    Parameters
    ----------
    shapes : ndarray, shape (n_labels, n_modes)
        Mass-normalised mode shapes at the DOFs ``labels`` (m/sqrt(kg)); NaN rows are ignored.
    freqs_Hz : ndarray, shape (n_modes,)
        Natural frequencies (Hz).
    labels : list of str
        ``"<point>:<direction>"`` of each row of ``shapes``.
    setup : MeasurementSetup
        Excitation and response DOFs; labels not among ``labels`` are ignored.
    zeta : float or ndarray
        Modal damping ratio(s).

    Returns
    -------
    ndarray, shape (n_modes,)
        ``sum_k sum_j |phi_jr| |phi_kr| / (2 zeta_r w_r^2)`` over excitation ``k`` and response ``j``.
    """
    shapes = np.nan_to_num(np.asarray(shapes, float))
    row = {lab: i for i, lab in enumerate(labels)}
    exc = [row[lab] for lab in setup.excitation if lab in row]
    resp = [row[lab] for lab in setup.response if lab in row]
    if not exc or not resp:
        return np.zeros(shapes.shape[1])
    w2 = (2 * np.pi * np.asarray(freqs_Hz, float)) ** 2
    summed = np.abs(shapes[exc]).sum(axis=0) * np.abs(shapes[resp]).sum(axis=0)
    with np.errstate(divide="ignore"):  # a rigid-body mode (0 Hz) is infinitely visible, and outside every band
        return summed / (2 * np.asarray(zeta, float) * w2)


def clearly_visible(vis: np.ndarray, paired: np.ndarray, threshold: float = VISIBLE_THRESHOLD) -> np.ndarray:
    """Which modes the test would clearly have seen: visibility at least ``threshold`` times the
    weakest paired mode's (``paired``: indices of the modes a measured mode is paired with).

    Returns a boolean mask over the modes; all False when nothing is paired.
    """
    vis = np.asarray(vis, float)
    paired = np.asarray(paired, int)
    paired = paired[paired >= 0]
    if paired.size == 0:
        return np.zeros(vis.shape, bool)
    return vis >= threshold * float(vis[paired].min())


def nearest_measured(f_model: np.ndarray, f_meas: np.ndarray) -> np.ndarray:
    """For each model frequency, the nearest measured frequency in log distance (Hz).

    An unpaired but clearly visible model mode is scored by its distance to the nearest measured mode:
    one close to a measured mode may have merged with it in the test (a small misfit), one far from
    any is a mode the test shows nothing of (a large one).
    """
    f_model = np.atleast_1d(np.asarray(f_model, float))
    f_meas = np.asarray(f_meas, float)
    with np.errstate(divide="ignore"):  # a rigid-body mode (0 Hz) is nearest to the lowest measured one
        d = np.abs(np.log(f_model)[:, None] - np.log(f_meas)[None, :])
    return f_meas[np.argmin(np.nan_to_num(d, nan=np.inf), axis=1)]


def misfit_target(f_model: np.ndarray, f_meas: np.ndarray, band_Hz: tuple) -> np.ndarray:
    """For each unpaired model frequency inside the test band, what it is scored against (Hz): the
    nearest measured frequency or the nearer band edge, whichever is nearer in log distance.

    A mode just inside the band edge that the test did not list is explained as well by moving out
    of the band as by merging with a measured mode: its misfit is the smaller of the two distances
    (a mode mid-band, far from every measured mode and edge, stays a large misfit).
    """
    f_model = np.atleast_1d(np.asarray(f_model, float))
    near = nearest_measured(f_model, f_meas)
    lo, hi = float(band_Hz[0]), float(band_Hz[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        edge = np.where(np.abs(np.log(f_model / lo)) < np.abs(np.log(hi / f_model)), lo, hi)
        use_edge = np.abs(np.log(f_model / edge)) < np.abs(np.log(f_model / near))
    return np.where(use_edge & (f_model > 0), edge, near)
