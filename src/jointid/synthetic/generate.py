"""Synthetic measured datasets with hidden effects (for proving the diagnosis).

``python -m jointid.synthetic.generate --truth TRUTH.yaml --out DIR [--config config.yaml ...]``

A truth file describes the "real" rig: true joint stiffnesses, library effects at given magnitudes
(``jointid.diagnosis.effects``), optional perturbations *outside* the library (decoys), optionally a finer mesh,
the operating states, what is measured and the noise.  The synthesiser solves the full FE model and
writes a dataset in the measurement format (``jointid.data.dataset.write_dataset``): natural
frequencies, damping ratios, mode shapes at the measuring points and optionally a drive-point FRF.  Nothing of the truth
except the measured inputs (motor force per state, frequency uncertainty) reaches the dataset; the
diagnosis never reads the truth file.

Truth file (all keys optional except ``states``)::

    base_config: [config.yaml]           # config files merged in order (relative to the truth file's
                                         # working directory); --config on the command line wins
    overrides: {mesh: {refine: 2}}       # merged into the config of the truth model
    joints: {k_normal_N_per_m3: 8.0e+11} # true joint stiffnesses; default geometric mean of bounds
    states: {power_off: {em_force_N: 0.0}, power_on: {em_force_N: 1000.0}}
    effects: {em_preload: {beta: 0.2}}   # library effects: parameter values and options
    perturbations:                       # outside the library (decoys)
      - {kind: carriage_joint_scale, carriage: 0, factor: 0.4}    # one carriage's joint layers
      - {kind: term_scale, term: K_railfix, factor: 0.5}          # any stiffness/mass term
    measurement: {band_Hz: [100, 3500], max_modes: 12, shapes: true, directions: [x, y, z],
                  frf: false, drive_point: T05, drive_direction: y, n_freq: 400}
    noise: {seed: 1, frequency_pct: 0.2, shape_pct: 2.0, damping_ratio: 0.02,
            stated_frequency_pct: 0.1,      # what the dataset states (default: frequency_pct);
                                            # set it below frequency_pct to understate the noise
            stated_shape_pct: 2.0}          # shape_uncertainty_pct stated (default: shape_pct)
    joint_loss_factors: {k_normal_N_per_m3: 0.08}   # hidden joint damping per joint parameter
    zeta0: 0.004                                     # hidden structural damping ratio

With ``joint_loss_factors`` and/or ``zeta0`` (default 0), the damping ratio of every mode follows the
hysteretic law ``zeta_r = zeta0 + sum_j eta_j e_rj / 2`` (``e_rj`` the share of mode r's strain energy in
the joint layers of parameter j, at the state's coefficients), the drive-point FRF uses these ratios,
and ``noise.damping_pct`` (relative, 1 sigma, seeded apart from the other noise) perturbs the measured
ratios; ``noise.stated_damping_pct`` (default ``damping_pct``) goes into conditions.yaml as
``damping_uncertainty_pct``.  Without them the ratios are ``noise.damping_ratio`` with 10 % scatter.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from jointid.config.synthetic import identification_config, truth_config  # noqa: F401  (truth_config: for callers)
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.data.dataset import write_dataset
from jointid.diagnosis.effects import apply_effects, enabled_effects
from jointid.diagnosis.terms import StateInfo, baseline_coefficients, build_system, term_component
from jointid.errors import ConfigError, JointidError
from jointid.fe.modal import solve_model
from jointid.fe.model import build_model, joint_terms
from jointid.response.damping import joint_energy_share
from jointid.response.drive_point import joint_stiffness
from jointid.response.harmonic import frf_modal
from jointid.threads import limit_threads
from jointid.yamlio import read_merged, read_yaml

__all__ = ["synthesise", "write_synthetic", "load_truth", "main", "joint_shares", "hysteretic_ratios"]

TRUTH_KEYS = {"description", "base_config", "overrides", "joints", "states", "effects", "perturbations",
              "measurement", "noise", "joint_loss_factors", "zeta0"}
MEASUREMENT_DEFAULTS = {"band_Hz": [100.0, 3500.0], "max_modes": 12, "shapes": True,
                        "directions": ["x", "y", "z"], "frf": False, "drive_point": "T05",
                        "drive_direction": "y", "n_freq": 400}
NOISE_DEFAULTS = {"seed": 0, "frequency_pct": 0.2, "shape_pct": 2.0, "damping_ratio": 0.02}
DAMPING_STREAM = 40  # the damping noise's own random stream (seed, 40): issue 40


def load_truth(path) -> dict:
    """Read and check a truth file; raise :class:`ConfigError` listing every problem."""
    path = Path(path)
    truth = read_yaml(path, str(path)) or {}
    if not isinstance(truth, dict):
        raise ConfigError(f"{path}: the truth file is not a mapping of keys — see the example in "
                          "jointid.synthetic.generate")
    check_truth(truth, str(path))
    return truth


def check_truth(truth: dict, where: str = "truth") -> None:
    """Raise :class:`ConfigError` listing every unknown key, missing state list or unknown perturbation."""
    problems = []
    for k in truth:
        if k not in TRUTH_KEYS:
            problems.append(f"{where}: {k}: unknown key — allowed keys: {', '.join(sorted(TRUTH_KEYS))}")
    if not truth.get("states"):
        problems.append(f"{where}: states: missing — give e.g. states: {{power_off: {{em_force_N: 0.0}}}}")
    for i, p in enumerate(truth.get("perturbations") or []):
        if p.get("kind") not in ("carriage_joint_scale", "term_scale"):
            problems.append(f"{where}: perturbations[{i}].kind: {p.get('kind')!r} is unknown — use "
                            "carriage_joint_scale or term_scale")
    for name, eta in (truth.get("joint_loss_factors") or {}).items():
        if not isinstance(eta, (int, float)) or not eta >= 0:
            problems.append(f"{where}: joint_loss_factors.{name}: {eta!r} is not a loss factor >= 0")
    if not isinstance(truth.get("zeta0", 0.0), (int, float)) or not truth.get("zeta0", 0.0) >= 0:
        problems.append(f"{where}: zeta0: {truth['zeta0']!r} is not a damping ratio >= 0")
    if problems:
        raise ConfigError(problems)


def _perturb(system, kc, mc, perturbations):
    for p in perturbations or []:
        if p["kind"] == "carriage_joint_scale":
            c = int(p["carriage"])
            dirs = set(p.get("directions") or ())  # none given: every direction or component
            for name in list(kc):
                if name.endswith(f"@{c}") and (not dirs or term_component(name) in dirs):
                    kc[name] *= float(p["factor"])
        elif p["kind"] == "term_scale":
            t = p["term"]
            if t in system.stiffness:
                kc[t] = kc.get(t, 0.0) * float(p["factor"])
            elif t in system.mass:
                mc[t] = mc.get(t, 0.0) * float(p["factor"])
            else:
                raise ConfigError(f"perturbations: term {t!r} is not a model term — use one of "
                                  f"{', '.join(list(system.stiffness) + list(system.mass))}")


def synthesise(truth: dict, settings: DiagnosisSettings, *, model=None) -> dict:
    """Solve the truth model and return the dataset tables.

    Parameters
    ----------
    truth : dict
        Parsed truth file (see module doc).
    settings : DiagnosisSettings
        Of the truth model's configuration (:func:`jointid.config.synthetic.truth_config`: the base configuration
        with the truth's ``overrides`` merged in).
    model : fem.Model, optional
        A model already built for exactly the truth configuration (saves the assembly).

    Returns
    -------
    dict
        ``modes``, ``shapes`` (or None), ``frf`` (or None) DataFrames and ``conditions`` dict, ready
        for :func:`jointid.data.dataset.write_dataset`; plus ``truth_freqs_Hz`` per state (noise-free)
        and ``truth_damping`` per state with hidden joint damping (:func:`_hidden_damping`).
    """
    check_truth(truth)
    spec = settings.model
    model = model or build_model(spec)
    system = build_system(model, spec)
    meas = {**MEASUREMENT_DEFAULTS, **(truth.get("measurement") or {})}
    noise = {**NOISE_DEFAULTS, **(truth.get("noise") or {})}
    rng = np.random.default_rng(int(noise["seed"]))
    rng_damping = np.random.default_rng([int(noise["seed"]), DAMPING_STREAM])  # apart: the rest stays as it was
    specs = enabled_effects(truth.get("effects") or {})
    theta = {k: float(v) for k, v in (truth.get("joints") or {}).items()}
    pts = system.meta["points"]
    labels = system.labels
    keep_rows = [i for i, lab in enumerate(labels) if lab.split(":")[1] in meas["directions"]]
    lo, hi = map(float, meas["band_Hz"])
    modes_rows, shape_rows, frf_rows, conds, clean, truth_damping = [], [], [], {}, {}, {}
    truncated = False
    for sname, scfg in truth["states"].items():
        state = StateInfo(sname, float((scfg or {}).get("em_force_N", 0.0)))
        kc, mc = baseline_coefficients(system, spec, theta)
        kc, mc = apply_effects(system, kc, mc, state, [(s.effect, s.values, s.options) for s in specs])
        _perturb(system, kc, mc, truth.get("perturbations"))
        n = int(meas["max_modes"]) + 8
        modes = solve_model(system, kc, mc, n, shift_Hz=settings.shift_Hz, backend=settings.backend)
        in_band = np.flatnonzero((modes.freqs_Hz >= lo) & (modes.freqs_Hz <= hi))
        sel = in_band[: int(meas["max_modes"])]
        truncated = truncated or len(in_band) > len(sel)
        f_true = modes.freqs_Hz[sel]
        clean[sname] = f_true
        f_noisy = f_true * (1 + noise["frequency_pct"] / 100 * rng.standard_normal(len(sel)))
        order = np.argsort(f_noisy)
        zeta = noise["damping_ratio"] * (1 + 0.1 * rng.standard_normal(len(sel)))
        zeta_all = None
        if {"joint_loss_factors", "zeta0"} & set(truth):  # hidden damping (else as before this key existed)
            zeta, zeta_all, truth_damping[sname] = _hidden_damping(system, spec, kc, modes, truth, sel, rng_damping)
        shapes = (system.probe @ modes.phi[:, sel])
        for new, j in enumerate(order):
            modes_rows.append({"state": sname, "mode": new + 1, "freq_Hz": float(f_noisy[j]),
                               "damping_ratio": float(np.clip(zeta[j], 1e-4, 0.5))})
            if meas["shapes"]:
                v = shapes[keep_rows, j]
                v = v / np.abs(v).max()
                rms = np.sqrt(np.mean(v ** 2))
                v = v + noise["shape_pct"] / 100 * rms * rng.standard_normal(len(v))
                for i, val in zip(keep_rows, v):
                    point, direction = labels[i].split(":")
                    shape_rows.append({"state": sname, "mode": new + 1, "point": point,
                                       "direction": direction, "value": float(val)})
        cond = {"em_force_N": state.em_force_N}
        if meas["frf"]:
            frf_rows += drive_point_frf(system, modes, sname, meas,
                                        noise["damping_ratio"] if zeta_all is None else zeta_all)
            cond.update({"frf_drive_point": meas["drive_point"], "frf_drive_direction": meas["drive_direction"]})
        conds[sname] = cond
    conditions = _conditions(noise, conds, None if truncated else [lo, hi], bool(truth_damping), bool(meas["shapes"]))
    conditions["computed_on_mesh"] = settings.mesh_digest  # the truth's discretisation (diagnosis.mesh_error)
    return {"modes": pd.DataFrame(modes_rows),
            "shapes": pd.DataFrame(shape_rows) if shape_rows else None,
            "frf": pd.DataFrame(frf_rows) if frf_rows else None,
            "conditions": conditions, "truth_freqs_Hz": clean, "points": pts, "truth_damping": truth_damping}


def _conditions(noise: dict, states: dict, band_Hz, damped: bool, shapes: bool = False) -> dict:
    """conditions.yaml of the synthetic dataset: source, stated uncertainties, the states and, when every
    mode in the band was measured (``band_Hz`` not None), the test's band.  With shapes, the stated
    ``shape_uncertainty_pct`` is ``noise.stated_shape_pct`` (default ``shape_pct``: the noise added is
    exactly that fraction of each mode's noise-free RMS over the measured directions)."""
    conditions = {"source": f"synthetic dataset (jointid.synthetic.generate), noise seed {int(noise['seed'])}",
                  "frequency_uncertainty_pct": float(noise.get("stated_frequency_pct") or noise["frequency_pct"]),
                  "states": states}
    if band_Hz is not None:  # every mode in the band was measured: the test declares its band
        conditions["test_setup"] = {"band_Hz": band_Hz}
    stated = float(noise.get("stated_damping_pct") or noise.get("damping_pct") or 0.0)
    if damped and stated > 0:
        conditions["damping_uncertainty_pct"] = stated
    stated_shape = float(noise.get("stated_shape_pct") or noise.get("shape_pct") or 0.0)
    if shapes and stated_shape > 0:
        conditions["shape_uncertainty_pct"] = stated_shape
    return conditions


def _hidden_damping(system, spec, kc, modes, truth, sel, rng):
    """The truth's hysteretic joint damping in one state: ``(measured ratios of the modes sel, with the
    relative noise noise.damping_pct; ratios of every solved mode; the truth's record)``."""
    meas = {**MEASUREMENT_DEFAULTS, **(truth.get("measurement") or {})}
    pct = float({**NOISE_DEFAULTS, **(truth.get("noise") or {})}.get("damping_pct", 0.0))
    zeta_all, shares = hysteretic_ratios(system, spec, kc, modes, truth)
    zeta = zeta_all[sel] * (1 + pct / 100 * rng.standard_normal(len(sel)))
    return zeta, zeta_all, {"freqs_Hz": modes.freqs_Hz, "damping_ratio": zeta_all, "shares": shares,
                            "measured_modes": sel, "drive_participation": drive_participation(system, modes, meas)}


def joint_shares(system, phi, freqs_Hz, kc: dict, terms: dict[str, list[str]], names) -> np.ndarray:
    """Share of each mode's strain energy in the joint layers of each joint parameter.

    Parameters
    ----------
    system : jointid.diagnosis.terms.System or jointid.fe.fem.Model
        Its ``stiffness`` terms (joint layers ``K_<face>_<d>`` or split per carriage ``K_<face>_<d>@<c>``).
    phi : ndarray, shape (n_dofs, n_modes)
        Mass-normalised modes.
    freqs_Hz : array_like, shape (n_modes,)
        Their frequencies (Hz), > 0.
    kc : dict
        Stiffness coefficients of the state (N/m^3 for the joint layers).
    terms : dict
        Joint parameter -> its layer terms (:func:`jointid.fe.model.joint_terms`).
    names : sequence of str
        The parameters of the columns.

    Returns
    -------
    ndarray, shape (n_modes, len(names))
        ``e_rj = phi_r^T (sum_t kc_t K_t) phi_r / w_r^2`` over parameter j's terms (dimensionless).
    """
    out = np.empty((len(freqs_Hz), len(names)))
    for j, name in enumerate(names):
        coeffs = {t: c for t, c in kc.items() if t.split("@")[0] in terms[name]}
        K_j = joint_stiffness(system, coeffs)
        if K_j.nnz == 0 and any(coeffs.values()):
            raise ConfigError(f"joint_loss_factors.{name}: its layers {terms[name]} are no joint-layer terms of "
                              "the model")
        out[:, j] = joint_energy_share(phi, freqs_Hz, K_j)
    return out


def hysteretic_ratios(system, spec, kc: dict, modes, truth: dict):
    """``(zeta (n_modes,), shares (n_modes, n_dirs))`` of every solved mode under the truth's hysteretic
    joint damping: ``zeta_r = zeta0 + sum_j eta_j e_rj / 2`` (``joint_loss_factors``, ``zeta0``; ``spec``: the
    truth's :class:`~jointid.config.typed.ModelSpec`)."""
    terms = joint_terms(spec.joints, spec.mesh_file)
    eta = {str(k): float(v) for k, v in (truth.get("joint_loss_factors") or {}).items()}
    unknown = sorted(set(eta) - set(terms))
    if unknown:
        raise ConfigError(f"joint_loss_factors: {', '.join(unknown)} not joint parameters — use one of "
                          f"{', '.join(terms)}")
    shares = joint_shares(system, modes.phi, modes.freqs_Hz, kc, terms, list(eta))
    return float(truth.get("zeta0", 0.0)) + shares @ np.array(list(eta.values())) / 2.0, shares


def drive_participation(system, modes, meas: dict) -> np.ndarray:
    """``p^T phi_r`` of every mode at the truth's drive point and direction (``measurement``)."""
    row = system.labels.index(f"{meas['drive_point']}:{meas['drive_direction']}")
    return np.asarray(system.probe[row] @ modes.phi).ravel()


def drive_point_frf(system, modes, state: str, meas: dict, damping_ratio: float) -> list[dict]:
    """Rows of the noise-free drive-point FRF of one state over the measured band.

    Parameters
    ----------
    system : jointid.diagnosis.terms.System
    modes : modal solution of the state (``freqs_Hz``, ``phi``)
    state : str
    meas : dict
        The truth's ``measurement`` section (``drive_point``, ``drive_direction``, ``band_Hz``, ``n_freq``).
    damping_ratio : float or ndarray, shape (n_modes,)
        Modal damping ratio of every mode (one for all, or per mode).
    """
    lo, hi = map(float, meas["band_Hz"])
    drive = drive_participation(system, modes, meas)
    f_axis = np.linspace(lo, hi, int(meas["n_freq"]))
    H = frf_modal(f_axis, modes.freqs_Hz, damping_ratio, drive, drive)
    return [{"state": state, "point": meas["drive_point"], "direction": meas["drive_direction"],
             "freq_Hz": float(fq), "re": float(h.real), "im": float(h.imag)} for fq, h in zip(f_axis, H)]


def identification_rig(settings: DiagnosisSettings) -> dict:
    """The rig the synthetic diagnosis cases are analysed on (``settings``: of
    :func:`jointid.config.synthetic.identification_config`).  Returns ``{"settings", "model", "system",
    "solver"}`` (solver None: the first diagnosis makes it)."""
    limit_threads(1)
    model = build_model(settings.model)
    return {"settings": settings, "model": model, "system": build_system(model, settings.model), "solver": None}


def write_synthetic(truth: dict, settings: DiagnosisSettings, out_dir, *, model=None):
    """Synthesise and write the dataset folder ``out_dir`` (``settings``: of the truth model's configuration,
    see :func:`synthesise`); returns the :class:`jointid.data.dataset.Dataset`."""
    out = synthesise(truth, settings, model=model)
    return write_dataset(out_dir, out["modes"], out["shapes"], out["frf"], conditions=out["conditions"],
                         measuring_points=out["points"])


def main(argv: list[str] | None = None) -> int:
    """Command line: write the synthetic dataset of ``--truth`` to ``--out``; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m jointid.synthetic.generate",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", required=True, help="truth YAML file")
    ap.add_argument("--out", required=True, help="dataset folder to write")
    ap.add_argument("--config", nargs="*", default=None,
                    help="config files merged in order (default: the truth's base_config, else config.yaml)")
    args = ap.parse_args(argv)
    try:
        limit_threads(1)
        truth = load_truth(args.truth)
        paths = args.config or truth.get("base_config") or ["config.yaml"]
        if isinstance(paths, str):
            paths = [paths]
        ds = write_synthetic(truth, DiagnosisSettings.from_config(truth_config(truth, read_merged(paths))), args.out)
    except JointidError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    n = {s: len(ds.freqs(s)) for s in ds.states}
    print(f"synth: wrote {args.out} ({', '.join(f'{s}: {k} modes' for s, k in n.items())})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
