"""Linear-motor normal force, its indirect measurement, and its share on each carriage block.

The coil primaries ride on the table above the magnet track, so the motor pulls the table (and the
carriage blocks) onto the rails with a vertical force ``Fc`` that is typically 2-5 times the thrust.
That force raises the contact pressure in the carriage/rail joints, which raises the joint stiffness
(see ``docs/effects.md``, effect ``em_preload``).

References
----------
The seed paper (``shared/seed/000_a95a938db2b2984b.txt``), eqs. (1)-(3) and Fig. 2:

* attraction ``Fd = Kd Lm Im^2``, eddy-current repulsion ``Fu = Ku Io^2``, resultant
  ``Fc = Kd Lm Im^2 - Ku Io^2``;
* indirect measurement: a dial indicator reads the carriage deflection with the motor powered; a
  loading device then reproduces the same reading with a known force, which equals ``Fc``.

Sign convention: a positive force presses the table onto the rails (compression of the blocks).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from jointid.errors import DataError, NumericalWarning

__all__ = [
    "IndicatorForce",
    "carriage_loads_N",
    "contact_pressure_Pa",
    "force_from_indicator",
    "vertical_force_N",
]


def _as_checked(name: str, value, problems: list[str], *, fix: str, allow_negative: bool = False):
    """Convert ``value`` to a float array; append a problem line if missing, non-finite or negative."""
    if value is None:
        problems.append(f"{name}: missing; {fix}")
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        problems.append(f"{name} = {value!r} is not a number; {fix}")
        return None
    if arr.size == 0:
        problems.append(f"{name}: empty; {fix}")
        return None
    if not np.all(np.isfinite(arr)):
        problems.append(f"{name} = {value!r} contains NaN/inf (missing value); {fix}")
        return None
    if not allow_negative and np.any(arr < 0):
        problems.append(f"{name} = {value!r} is negative; {fix}")
        return None
    return arr


def _scalar_or_array(x: np.ndarray):
    return float(x) if np.ndim(x) == 0 else x


def vertical_force_N(attraction_constant, inductance_H, exciting_current_A, repulsion_constant,
                     eddy_current_A):
    """Resultant vertical force of a linear motor, ``Fc = Kd Lm Im^2 - Ku Io^2`` (paper eq. 3).

    Parameters
    ----------
    attraction_constant : float or array_like
        ``Kd`` in N/(H*A^2) (since H*A^2 = J, equivalently 1/m), >= 0.
    inductance_H : float or array_like
        Magnetising inductance ``Lm`` in H, >= 0.
    exciting_current_A : float or array_like
        Exciting (magnetising) current ``Im`` in A (RMS magnitude), >= 0.
    repulsion_constant : float or array_like
        ``Ku`` in N/A^2, >= 0.
    eddy_current_A : float or array_like
        Secondary eddy current ``Io`` in A (RMS magnitude), >= 0.

    Returns
    -------
    float or ndarray
        ``Fc`` in N (broadcast shape of the inputs); positive = attraction, pressing the table onto
        the rails. A ``NumericalWarning`` is issued if the repulsion exceeds the attraction.

    Raises
    ------
    DataError
        One line per missing, non-numeric, non-finite or negative argument.
    """
    problems: list[str] = []
    kd = _as_checked("attraction_constant", attraction_constant, problems,
                     fix="give Kd in N/(H*A^2) as a number >= 0")
    lm = _as_checked("inductance_H", inductance_H, problems,
                     fix="give the magnetising inductance Lm in H as a number >= 0")
    im = _as_checked("exciting_current_A", exciting_current_A, problems,
                     fix="give the exciting current Im in A as a magnitude >= 0 (the force depends on Im^2)")
    ku = _as_checked("repulsion_constant", repulsion_constant, problems,
                     fix="give Ku in N/A^2 as a number >= 0")
    io = _as_checked("eddy_current_A", eddy_current_A, problems,
                     fix="give the secondary eddy current Io in A as a magnitude >= 0 (use 0 if unknown)")
    if problems:
        raise DataError(problems)
    fc = kd * lm * im**2 - ku * io**2
    if np.any(fc < 0):
        warnings.warn(
            f"vertical_force_N: resultant Fc = {fc} N is negative (eddy-current repulsion exceeds "
            "attraction); the motor lifts the table, check Kd, Ku and the currents",
            NumericalWarning, stacklevel=2)
    return _scalar_or_array(fc)


@dataclass(frozen=True)
class IndicatorForce:
    """Result of the indirect (dial-indicator) force measurement.

    Attributes
    ----------
    force_N : float
        Force reproducing the powered reading, taken as ``Fc`` (N).
    std_N : float
        Standard uncertainty of ``force_N`` (N); NaN when it cannot be estimated (2 calibration
        points leave no residual degree of freedom).
    intercept_um, slope_um_per_N : float
        Calibration line ``reading = intercept + slope * F``.
    residual_std_um : float
        Standard deviation of the calibration residuals, ``sqrt(SSR / (n - 2))`` (um).
    n_points : int
        Number of calibration points.
    extrapolated : bool
        True if the powered reading lies outside the calibrated reading range.
    """

    force_N: float
    std_N: float
    intercept_um: float
    slope_um_per_N: float
    residual_std_um: float
    n_points: int
    extrapolated: bool


def force_from_indicator(powered_reading_um, calibration_force_N, calibration_reading_um, *,
                         powered_reading_std_um: float = 0.0) -> IndicatorForce:
    """Infer the motor's normal force from the dial-indicator method (paper, Fig. 2).

    The calibration points (known force from the loading device, indicator reading) are fitted by
    least squares with ``reading = a + c F``; the force giving the powered reading ``y0`` is
    ``F0 = (y0 - a) / c``. Its standard uncertainty (inverse-prediction, first order) is::

        u(F0)^2 = (s / c)^2 * (1/n + (F0 - mean(F))^2 / Sxx) + (u(y0) / c)^2

    with ``s^2 = SSR / (n - 2)`` the residual variance and ``Sxx = sum (F - mean(F))^2``.

    Parameters
    ----------
    powered_reading_um : float
        Indicator reading with the motor powered (um), same zero as the calibration readings.
    calibration_force_N : array_like, shape (n,)
        Forces applied by the loading device (N). Repeated forces are allowed.
    calibration_reading_um : array_like, shape (n,)
        Indicator readings for those forces (um).
    powered_reading_std_um : float, optional
        Standard uncertainty of the powered reading itself (um), e.g. the indicator resolution
        divided by sqrt(12), or the scatter of repeated readings divided by sqrt(count). Default 0.

    Returns
    -------
    IndicatorForce

    Raises
    ------
    DataError
        Fewer than 2 distinct forces, length mismatch, non-finite values, or readings that are not
        strictly monotonic in the force (mean reading per distinct force).

    Warns
    -----
    NumericalWarning
        When the powered reading lies outside the calibrated reading range (extrapolation), or when
        only 2 calibration points are given (no uncertainty estimate).
    """
    y0, force, read, u_y0 = _indicator_inputs(powered_reading_um, calibration_force_N, calibration_reading_um,
                                              powered_reading_std_um)
    y0 = float(y0.ravel()[0])
    u_y0 = float(u_y0.ravel()[0])
    n = force.size
    f_mean = force.mean()
    sxx = float(np.sum((force - f_mean) ** 2))
    slope = float(np.sum((force - f_mean) * (read - read.mean())) / sxx)
    intercept = float(read.mean() - slope * f_mean)
    f0 = (y0 - intercept) / slope
    if n > 2:
        ssr = float(np.sum((read - intercept - slope * force) ** 2))
        s = np.sqrt(ssr / (n - 2))
        std = float(np.sqrt((s / slope) ** 2 * (1.0 / n + (f0 - f_mean) ** 2 / sxx) + (u_y0 / slope) ** 2))
    else:
        s = float("nan")
        std = float("nan")
        warnings.warn("force_from_indicator: only 2 calibration points, the force uncertainty cannot be "
                      "estimated from residuals; add calibration points", NumericalWarning, stacklevel=2)
    extrapolated = bool(y0 < read.min() or y0 > read.max())
    if extrapolated:
        warnings.warn(
            f"force_from_indicator: powered reading {y0} um is outside the calibrated range "
            f"[{read.min()}, {read.max()}] um; the force {f0:.4g} N is extrapolated, extend the "
            "calibration loads to bracket it", NumericalWarning, stacklevel=2)
    return IndicatorForce(force_N=float(f0), std_N=std, intercept_um=intercept, slope_um_per_N=slope,
                          residual_std_um=float(s), n_points=int(n), extrapolated=extrapolated)


def _indicator_inputs(powered_reading_um, calibration_force_N, calibration_reading_um, powered_reading_std_um):
    """The arguments of :func:`force_from_indicator` as arrays ``(y0, force, read, u_y0)`` (um, N, um,
    um; force and read flat); raise one :class:`DataError` listing every problem."""
    problems: list[str] = []
    y0 = _as_checked("powered_reading_um", powered_reading_um, problems, allow_negative=True,
                     fix="give the powered dial-indicator reading in um as one finite number")
    force = _as_checked("calibration_force_N", calibration_force_N, problems, allow_negative=True,
                        fix="give the loading-device forces in N, one finite number per calibration point")
    read = _as_checked("calibration_reading_um", calibration_reading_um, problems, allow_negative=True,
                       fix="give the indicator readings in um, one finite number per calibration point")
    u_y0 = _as_checked("powered_reading_std_um", powered_reading_std_um, problems,
                       fix="give the standard uncertainty of the powered reading in um, >= 0")
    if y0 is not None and y0.size != 1:
        problems.append(f"powered_reading_um: {y0.size} values given; give one reading (average repeats "
                        "and pass their standard error as powered_reading_std_um)")
    if force is not None and read is not None:
        force, read = force.ravel(), read.ravel()
        if force.size != read.size:
            problems.append(f"calibration_force_N has {force.size} values but calibration_reading_um has "
                            f"{read.size}; give one reading per applied force")
        else:
            levels = np.unique(force)
            if levels.size < 2:
                problems.append(f"calibration_force_N: {levels.size} distinct force(s); apply at least 2 "
                                "different forces (better 4-6 spanning the expected Fc)")
            else:
                means = np.array([read[force == lv].mean() for lv in levels])
                d = np.diff(means)
                if not (np.all(d > 0) or np.all(d < 0)):
                    problems.append("calibration_reading_um: readings are not strictly monotonic in the "
                                    f"applied force (mean per force {means.tolist()} um at {levels.tolist()} N); "
                                    "check the indicator zero, the load order and slipping of the indicator")
    if problems:
        raise DataError(problems)
    return y0, force, read, u_y0


def carriage_loads_N(force_N, table_mass_kg, carriage_x_m, carriage_z_m, load_x_m=0.0, load_z_m=0.0,
                     g=9.81):
    """Normal load on each carriage block of a rigid table on equally stiff supports.

    The total vertical load ``W = force_N + table_mass_kg * g`` acts at ``(load_x_m, load_z_m)``.
    A rigid table on equally stiff blocks settles as a plane, ``w_i = w0 + theta_z x_i + theta_x z_i``,
    so ``F_i = k w_i``; force and moment balance give the three unknowns. For four blocks at the
    corners of a rectangle ``(+-a, +-b)`` centred at the origin this reduces to::

        F_i = W / 4 * (1 + s_i x / a + t_i z / b),   s_i = sign(x_i), t_i = sign(z_i)

    (the twisting combination ``s_i t_i`` carries no load). Other layouts (>= 3 blocks, not on one
    line) are solved with the same plane assumption.

    Parameters
    ----------
    force_N : float
        Motor normal force ``Fc`` (N), positive pressing the table down.
    table_mass_kg : float
        Mass carried by the blocks (table, motor primaries, payload) in kg, >= 0.
    carriage_x_m, carriage_z_m : array_like, shape (n_blocks,)
        Block centre coordinates in m (X lateral, Z feed).
    load_x_m, load_z_m : float
        Point of action of the resultant ``W`` in m.
    g : float
        Gravitational acceleration in m/s^2, > 0.

    Returns
    -------
    ndarray, shape (n_blocks,)
        Block loads in N (positive = compression). Sum equals ``W``; the moments about the X and Z
        axes balance.

    Warns
    -----
    NumericalWarning
        If a block load is negative (the block would lift off; a preloaded block stays in contact,
        see ``contact_pressure_Pa``).
    """
    fc, m, x, z, lx, lz, gg = _carriage_inputs(force_N, table_mass_kg, carriage_x_m, carriage_z_m, load_x_m,
                                               load_z_m, g)
    w = float(fc) + float(m) * float(gg)
    lx, lz = float(lx), float(lz)
    # Plane of settlement: F_i = c0 + cx * x_i + cz * z_i; solve force and two moment balances.
    basis = np.column_stack([np.ones_like(x), x, z])          # (n, 3)
    rhs = np.array([w, w * lx, w * lz])                        # sum F, sum F x, sum F z
    coef = np.linalg.solve(basis.T @ basis, rhs)
    loads = basis @ coef
    if np.any(loads < 0):
        bad = np.flatnonzero(loads < 0).tolist()
        warnings.warn(
            f"carriage_loads_N: block(s) {bad} would carry a negative load {loads[bad]} N (lift-off "
            "without preload); the load offset is outside the blocks' middle region",
            NumericalWarning, stacklevel=2)
    return loads


def _carriage_inputs(force_N, table_mass_kg, carriage_x_m, carriage_z_m, load_x_m, load_z_m, g):
    """The arguments of :func:`carriage_loads_N` as arrays ``(fc, m, x, z, lx, lz, g)`` (N, kg, m, m, m,
    m, m/s^2; x and z flat); raise one :class:`DataError` listing every problem (>= 3 blocks, not on
    one line)."""
    problems: list[str] = []
    fc = _as_checked("force_N", force_N, problems, allow_negative=True,
                     fix="give the motor normal force in N as one finite number")
    m = _as_checked("table_mass_kg", table_mass_kg, problems, fix="give the carried mass in kg, >= 0")
    x = _as_checked("carriage_x_m", carriage_x_m, problems, allow_negative=True,
                    fix="give the block X coordinates in m, one per block")
    z = _as_checked("carriage_z_m", carriage_z_m, problems, allow_negative=True,
                    fix="give the block Z coordinates in m, one per block")
    lx = _as_checked("load_x_m", load_x_m, problems, allow_negative=True, fix="give the load X offset in m")
    lz = _as_checked("load_z_m", load_z_m, problems, allow_negative=True, fix="give the load Z offset in m")
    gg = _as_checked("g", g, problems, fix="give the gravitational acceleration in m/s^2, > 0")
    for name, v in (("force_N", fc), ("table_mass_kg", m), ("load_x_m", lx), ("load_z_m", lz), ("g", gg)):
        if v is not None and v.size != 1:
            problems.append(f"{name}: {v.size} values given; give a single number")
    if gg is not None and gg.size == 1 and float(gg) <= 0:
        problems.append(f"g = {float(gg)} is not positive; use 9.81 m/s^2")
    if x is not None and z is not None:
        x, z = x.ravel(), z.ravel()
        if x.size != z.size:
            problems.append(f"carriage_x_m has {x.size} values but carriage_z_m has {z.size}; "
                            "give both coordinates of every block")
        elif x.size < 3:
            problems.append(f"carriage_x_m: {x.size} block(s); a table needs >= 3 supports (usually 4)")
        else:
            a = np.column_stack([np.ones_like(x), x - x.mean(), z - z.mean()])
            if np.linalg.matrix_rank(a, tol=1e-9 * max(1.0, np.abs(a[:, 1:]).max())) < 3:
                problems.append("carriage_x_m/carriage_z_m: all blocks lie on one line; the table would "
                                "tip, check the coordinates")
    if problems:
        raise DataError(problems)
    return fc, m, x, z, lx, lz, gg


def contact_pressure_Pa(load_N, area_m2, preload_N=0.0):
    """Mean contact pressure of a carriage/rail joint, ``p = (load + preload) / area``.

    Parameters
    ----------
    load_N : float or array_like
        External normal load on the block (N), positive = compression.
    area_m2 : float or array_like
        Nominal joint contact area (m^2), > 0.
    preload_N : float or array_like, optional
        Block preload (N), >= 0.

    Returns
    -------
    float or ndarray
        Pressure in Pa. A ``NumericalWarning`` is issued where it is negative (the joint opens; a
        power law ``alpha * p**beta`` is undefined there).
    """
    problems: list[str] = []
    load = _as_checked("load_N", load_N, problems, allow_negative=True, fix="give the block load in N")
    area = _as_checked("area_m2", area_m2, problems, fix="give the joint contact area in m^2, > 0")
    pre = _as_checked("preload_N", preload_N, problems, fix="give the block preload in N, >= 0")
    if area is not None and np.any(area == 0):
        problems.append(f"area_m2 = {area_m2!r} contains zero; give the joint contact area in m^2, > 0")
    if problems:
        raise DataError(problems)
    p = (load + pre) / area
    if np.any(p < 0):
        warnings.warn(f"contact_pressure_Pa: negative pressure {p} Pa, the joint opens (lift-off); "
                      "its stiffness is zero there, not alpha * p**beta", NumericalWarning, stacklevel=2)
    return _scalar_or_array(p)
