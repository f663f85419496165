"""Typed results of the Python API (:class:`jointid.api.Study`): frozen dataclasses.

Each holds plain arrays and tables in SI units (Hz, N/m^3, m); the field docs give shapes and units.
The dataclasses compare by identity (``eq=False``): they hold arrays, whose ``==`` is element-wise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from jointid.correlate.pairing import PairedBy

__all__ = ["DiagnosisResult", "Identification", "MethodResult", "ModalResult"]


@dataclass(frozen=True, eq=False)
class ModalResult:
    """Modes of the FE model at one point of the joint parameters (:meth:`Study.modes`).

    Attributes
    ----------
    state : str
        The operating state the modes are labelled with (e.g. ``power_off``).
    theta : dict of str -> float
        Every joint parameter used, identified and fixed, in N/m^3 (stiffness per unit contact area
        and unit relative displacement; the names carry the unit, e.g. ``k_normal_N_per_m3``).
    freqs_Hz : ndarray, shape (n_modes,)
        Natural frequencies in Hz, ascending.
    shapes : ndarray, shape (n_labels, n_modes)
        Mass-normalised mode shapes at the measuring points, in m/sqrt(kg); row ``i`` is the
        displacement of ``labels[i]``.
    labels : tuple of str
        ``"<point>:<direction>"`` of each row of ``shapes``, e.g. ``"T05:y"`` (X lateral, Y vertical,
        Z feed).
    phi : ndarray, shape (n_dofs, n_modes)
        Mass-normalised mode shapes at every DOF of the model (m/sqrt(kg); interleaved ``ux, uy, uz``
        per node, zeros at clamped DOFs).
    energy : DataFrame
        One row per mode: ``description`` (e.g. ``table bounce``), the kinetic-energy share of each
        part (``kinetic_<part>``), the strain-energy share of each stiffness term (``strain_<term>``)
        and ``strain_joints``, the share stored in the carriage-rail joint layers (0..1).
    k_coefficients, m_coefficients : dict of str -> float
        The affine coefficients the model was assembled with: ``K = K0 + sum c_t K_t`` over the
        stiffness terms (joint layers ``K_<face>_<direction>`` in N/m^3, rail fixing ``K_railfix``
        in N/m^3, mounts ``K_mount`` in N/m^3 per unit mount area, material ratios of the solids)
        and ``M = M0 + sum c_t M_t`` (``M_motor``: the motor mass in kg spread on its patch, material
        density ratios).
    sturm : jointid.fe.modal.SturmCheck or None
        Completeness check of the solve (a Sturm count; ``None`` unless ``certify=True``).
    """

    state: str
    theta: dict[str, float]
    freqs_Hz: np.ndarray
    shapes: np.ndarray
    labels: tuple[str, ...]
    phi: np.ndarray
    energy: pd.DataFrame
    k_coefficients: dict[str, float]
    m_coefficients: dict[str, float]
    sturm: Any = None

    @property
    def descriptions(self) -> tuple[str, ...]:
        """Plain-language description of each mode, e.g. ``("table feed", "table bounce", ...)``."""
        return tuple(str(d) for d in self.energy["description"])

    def table(self) -> pd.DataFrame:
        """One row per mode: ``mode`` (1-based), ``freq_Hz``, ``description``, ``strain_joints``."""
        return pd.DataFrame({"mode": np.arange(1, len(self.freqs_Hz) + 1), "freq_Hz": self.freqs_Hz,
                             "description": list(self.descriptions),
                             "strain_joints": self.energy["strain_joints"].to_numpy(float)})

    def shape(self, mode: int) -> pd.DataFrame:
        """The shape of ``mode`` (1-based) at the measuring points: columns ``point, x, y, z``
        (m/sqrt(kg)), one row per point."""
        col = self.shapes[:, mode - 1]
        rows: dict[str, dict[str, float]] = {}
        for lab, v in zip(self.labels, col):
            point, d = lab.split(":")
            rows.setdefault(point, {})[d] = float(v)
        return pd.DataFrame([{"point": p, **v} for p, v in rows.items()])


@dataclass(frozen=True, eq=False)
class Identification:
    """Joint parameters fitted to one state's measured modes (:meth:`Study.identify`).

    Attributes
    ----------
    state : str
        The measured state.
    theta : dict of str -> float
        The fitted joint parameters, N/m^3.
    ci95_low, ci95_high : dict of str -> float
        95 % intervals of ``theta`` (N/m^3), from the Gauss-Newton covariance in log10 and the stated
        frequency uncertainty, widened by ``max(1, sqrt(chi2 / dof))`` as in the workflow.
    theta0 : dict of str -> float
        The start of the fit, N/m^3.
    f_meas_Hz, f_model_Hz : ndarray, shape (n_measured,)
        Measured frequencies and the paired model frequencies at ``theta``, Hz.
    tracking_mac : ndarray, shape (n_measured,)
        MAC of each paired model mode with its shape at the previous iterate (how well the fit
        followed the modes; not a test-analysis MAC, for which see :meth:`Study.compare`).
    paired_by : jointid.correlate.pairing.PairedBy
        ``PairedBy.MAC`` (measured shapes) or ``PairedBy.FREQUENCY`` (order-preserving frequency pairing
        re-done at every iterate); a ``str`` enum, so it equals ``"mac"`` or ``"frequency"``.
    chi2 : float
        Frequency chi-square at ``theta`` with the stated uncertainty (dimensionless), the misfits
        of ``unpaired_visible`` included.
    dof : int
        Residual degrees of freedom (measured modes minus parameters, at least 1).
    iterations : int
        Gauss-Newton iterations run.
    on_bound : tuple of str
        Parameters that ended on a bound of ``joints.parameters``.
    fixed : dict of str -> float
        Joint parameters held at their configured value (``joints.fixed``), N/m^3.
    unpaired_visible : tuple of dict
        Model modes the test would clearly have seen that no measured mode takes (``freq_Hz``,
        ``target_Hz``, ``misfit_pct``, ``visibility_rel``), each a misfit of the fit.
    shape_chi2, shape_dof : float, int
        The shape rows' chi-square at their stated (or estimated) uncertainty and their degrees of
        freedom (rows less one scale per mode), where measured shapes were fitted; 0 and 0 without.
    """

    state: str
    theta: dict[str, float]
    ci95_low: dict[str, float]
    ci95_high: dict[str, float]
    theta0: dict[str, float]
    f_meas_Hz: np.ndarray
    f_model_Hz: np.ndarray
    tracking_mac: np.ndarray
    paired_by: PairedBy
    chi2: float
    dof: int
    iterations: int
    on_bound: tuple[str, ...]
    fixed: dict[str, float]
    unpaired_visible: tuple[dict, ...] = ()
    shape_chi2: float = 0.0
    shape_dof: int = 0

    @property
    def residual_pct(self) -> np.ndarray:
        """``100 (f_model - f_meas) / f_meas`` per measured mode, shape (n_measured,)."""
        return 100 * (self.f_model_Hz - self.f_meas_Hz) / self.f_meas_Hz

    @property
    def max_abs_error_pct(self) -> float:
        """The largest ``|residual_pct|``."""
        return float(np.max(np.abs(self.residual_pct)))

    def table(self) -> pd.DataFrame:
        """One row per fitted parameter: ``parameter, start_N_per_m3, value_N_per_m3, ci95_low_N_per_m3,
        ci95_high_N_per_m3, on_bound``."""
        return pd.DataFrame([{"parameter": n, "start_N_per_m3": self.theta0[n], "value_N_per_m3": v,
                              "ci95_low_N_per_m3": self.ci95_low[n], "ci95_high_N_per_m3": self.ci95_high[n],
                              "on_bound": n in self.on_bound} for n, v in self.theta.items()])

    def modes_table(self) -> pd.DataFrame:
        """One row per measured mode: ``mode, measured_Hz, model_Hz, error_pct``."""
        return pd.DataFrame({"mode": np.arange(1, len(self.f_meas_Hz) + 1), "measured_Hz": self.f_meas_Hz,
                             "model_Hz": self.f_model_Hz, "error_pct": self.residual_pct})


@dataclass(frozen=True, eq=False)
class MethodResult:
    """The paper's method run on every configured state (:meth:`Study.run_method`): what the workflow writes
    to ``results/identify/<state>/`` and ``results/tables/``.

    Attributes
    ----------
    identifications : dict of str -> jointid.identification.record.IdentificationRecord
        Per state, its ``params.json``: the joint parameters (``.theta``, N/m^3) with their 95 % intervals
        (``.parameters``), the surface optimum, the pairing, the FE polish, the mesh extrapolation, notes.
    verified : dict of str -> DataFrame
        Per state, its ``verify.csv``: one row per measured mode (``order, experimental_Hz, simulation_Hz,
        relative_error_pct, ..., fe_mode, mac_to_tracked, description``), the full FE solve at the parameters.
    unpaired : dict of str -> DataFrame
        Per state, its ``unpaired_visible.csv``: model modes the test would clearly have seen that no measured
        mode takes (``model_mode, freq_Hz, target_Hz, misfit_pct, visibility_rel, description``).
    tables : dict of str -> DataFrame
        Per state, its table of natural frequencies (Table 2: ``power_off``, Table 3: ``power_on``):
        ``order, experimental_Hz, simulation_Hz, relative_error_pct, paper_simulation_Hz,
        paper_relative_error_pct`` (the paper's columns empty on other data).
    surface : dict
        The response-surface model the states were identified on (``results/surface/.../model.json``).
    """

    identifications: dict[str, Any]
    verified: dict[str, pd.DataFrame]
    unpaired: dict[str, pd.DataFrame]
    tables: dict[str, pd.DataFrame]
    surface: dict

    def theta(self, state: str) -> dict[str, float]:
        """The identified joint parameters of ``state``, N/m^3."""
        return dict(self.identifications[state].theta)

    def max_abs_error_pct(self, state: str) -> float:
        """The largest ``|relative_error_pct|`` of ``state``'s table."""
        return float(self.tables[state]["relative_error_pct"].abs().max())

    def write(self, folder) -> list[str]:
        """Write the workflow's files of each state under ``folder``: ``identify/<state>/params.json``,
        ``verify.csv`` and ``unpaired_visible.csv`` (as in ``results/``), and its table as ``tables/<state>.csv``
        (the workflow's ``tables/table2_power_off.csv`` ...), in the workflow's formats; returns the paths."""
        from pathlib import Path

        from jointid import io

        out = []
        for state, rec in self.identifications.items():
            folder_ = Path(folder) / "identify" / state
            out += [str(folder_ / "params.json"), str(folder_ / "verify.csv"), str(folder_ / "unpaired_visible.csv"),
                    str(Path(folder) / "tables" / f"{state}.csv")]
            rec.write(out[-4])
            io.write_csv(self.verified[state], out[-3])
            io.write_csv(self.unpaired[state], out[-2])
            io.write_csv(self.tables[state], out[-1])
        return out


@dataclass(frozen=True, eq=False)
class DiagnosisResult:
    """Which effect the model lacks (:meth:`Study.diagnose`); the tables are those of
    ``results/diagnosis/<name>/`` (docs/effects.md).

    Attributes
    ----------
    verdict : str
        The verdict in words.
    explained_by : str
        The effect (or ``A+B`` pair) that explains the data, ``unexplained``, or the text the loop
        gives when the current model already fits.
    ranking : DataFrame
        The library effects, best first (``effect, explained_fraction, score, p_value, delta_aicc,
        explains, estimate, ...``).
    ladder : DataFrame
        Per-state max/RMS error (%) of baseline -> +enabled effects -> +suggested effect.
    compare : DataFrame
        The baseline against every measured mode (``state, mode, freq_meas_Hz, freq_model_Hz,
        error_pct, mac, status, ...``).
    timing_s : float
        Wall time of the loop, s.
    raw : jointid.diagnosis.loop.Diagnosis
        Everything the loop found (fits, drift, MAC matrices, next measurements ...).
    """

    verdict: str
    explained_by: str
    ranking: pd.DataFrame
    ladder: pd.DataFrame
    compare: pd.DataFrame
    timing_s: float
    raw: Any

    @property
    def top_effect(self) -> str | None:
        """The best-ranked library effect (None when nothing was tested)."""
        return None if self.ranking.empty else str(self.ranking["effect"].iloc[0])

    def ladder_summary(self) -> pd.DataFrame:
        """The largest state error per rung of the ladder: columns ``variant, max_abs_error_pct``."""
        g = self.ladder.groupby("variant", sort=False)["max_abs_error_pct"].max()
        return g.reset_index()
