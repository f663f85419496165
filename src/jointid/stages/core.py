"""One function per workflow stage: read inputs, call the package, write outputs atomically.

The Snakemake scripts in ``workflow/scripts`` are adapters around these functions, and every stage
can be run from a plain Python session as well.

Imports of the numerical modules are inside the functions that need them: every workflow job is a
fresh Python process, and a job should load only what its stage uses (e.g. the modal fan-out never
needs ``scipy.stats``, the tables never need the FE code).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from jointid import io

if TYPE_CHECKING:
    import pandas as pd


def _log(msg: str) -> None:
    print(msg, flush=True)


# ------------------------------------------------------------------ mesh
def run_mesh(cfg: dict, matrices: str, points_csv: str | None = None, vtu: str | None = None,
             extra_edge_levels: int = 0) -> None:
    """Build and cache the model matrices, the measuring-point table and a VTK file of the mesh;
    ``extra_edge_levels``: the matrices alone of the mesh with that many more edge levels."""
    import pandas as pd

    from jointid.fe.extrapolate import level_config
    from jointid.fe.modal import model_ordering
    from jointid.fe.model import build_model, save_model

    model = build_model(level_config(cfg, extra_edge_levels), progress=_log)
    model.ordering = model_ordering(model)  # the pattern, so its ordering, is the same at any shift
    save_model(model, matrices)
    if points_csv is None:
        _log(f"mesh: wrote {matrices} ({model.n_dofs} DOFs)")
        return
    pts = pd.DataFrame(model.meta["points"])
    io.write_csv(pts, points_csv)
    io.write_json(str(points_csv).replace("measuring_points.csv", "summary.json"), model_summary(model))
    if vtu:
        from jointid.fe.vtk import write_mesh_vtu

        write_mesh_vtu(model, vtu)
    _log(f"mesh: wrote {matrices} ({model.n_dofs} DOFs), {points_csv}")


def model_summary(model) -> dict:
    """Sizes and areas of the model (for per-carriage conversions and reports)."""
    m = model.meta
    per = {face: a / 4 for face, a in m["contact_area_m2"].items()}
    per["flank+top"] = per["top"] + per["flank"]
    return {"n_dofs": m["n_dofs"], "n_elements": m["n_elements"], "element": m["element"],
            "support": m["support"], "contact_area_m2": m["contact_area_m2"],
            "contact_area_per_carriage_m2": per, "motor_mass_kg": m["motor_mass_kg"],
            "dims_m": m["dims_m"], "carriage_centres_m": m["carriage_centres_m"]}


# ------------------------------------------------------------------ doe
def parameter_names(cfg: dict) -> list[str]:
    return list(cfg["joints"]["parameters"])


def parameter_bounds(cfg: dict) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the identified parameters (``joints.parameters``, N/m^3)."""
    names = parameter_names(cfg)
    return (np.array([float(cfg["joints"]["parameters"][n]["lower"]) for n in names]),
            np.array([float(cfg["joints"]["parameters"][n]["upper"]) for n in names]))


def doe_sheet(cfg: dict, lower=None, upper=None) -> pd.DataFrame:
    """The DOE as a sample sheet: one row per FE solve (design points, then verification points).

    Columns: ``point, role, x_<param>`` (coded in [-1, 1] over log10 of the parameter) and
    ``<param>`` (physical, N/m^3).  The box is ``joints.parameters``' bounds unless ``lower`` and
    ``upper`` (N/m^3) are given (the zoomed second DOE, :func:`zoom_box`).
    """
    import pandas as pd

    from jointid.identification.doe import design, to_physical, verification_points

    names = parameter_names(cfg)
    d = cfg["doe"]
    X = design(d["design"], len(names), n_center=d["n_center"], n_samples=d.get("n_samples", 0),
               seed=d["seed"])
    V = verification_points(d["n_verification"], len(names), seed=d["seed"] + 1)
    lo, hi = parameter_bounds(cfg)
    if lower is not None:
        lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    rows = []
    for role, block in (("design", X), ("verify", V)):
        theta = to_physical(block, lo, hi)
        for i in range(len(block)):
            row = {"point": f"{role[0]}{i:03d}", "role": role}
            row.update({f"x_{n}": float(block[i, j]) for j, n in enumerate(names)})
            row.update({n: float(theta[i, j]) for j, n in enumerate(names)})
            rows.append(row)
    return pd.DataFrame(rows)


def run_doe(cfg: dict, out_csv: str) -> None:
    sheet = doe_sheet(cfg)
    io.write_csv(sheet, out_csv)
    _log(f"doe: {int((sheet.role == 'design').sum())} design + {int((sheet.role == 'verify').sum())} "
         f"verification points -> {out_csv}")


def zoom_enabled(cfg: dict) -> bool:
    return bool((cfg["doe"].get("zoom") or {}).get("enabled", False))


def zoom_half_width(cfg: dict) -> float:
    """``doe.zoom.half_width_decades`` (decades of the parameter)."""
    return float((cfg["doe"].get("zoom") or {}).get("half_width_decades", 0.15))


def zoom_box(cfg: dict, optima: dict[str, dict[str, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Box of the zoomed second DOE around the first-stage optima of all states (N/m^3).

    Per parameter: ``[min over states / 10^w, max over states * 10^w]`` with ``w =
    doe.zoom.half_width_decades``, clipped to the bounds of ``joints.parameters``; a box squeezed
    against a bound keeps its full width ``2 w`` on the inside.
    """
    names = parameter_names(cfg)
    w = zoom_half_width(cfg)
    lo_b, hi_b = np.log10(parameter_bounds(cfg)[0]), np.log10(parameter_bounds(cfg)[1])
    opt = np.log10(np.array([[float(o[n]) for n in names] for o in optima.values()]))
    lo, hi = opt.min(axis=0) - w, opt.max(axis=0) + w
    span = np.minimum(hi - lo, hi_b - lo_b)
    lo, hi = np.maximum(lo, lo_b), np.minimum(hi, hi_b)
    hi = np.maximum(hi, np.minimum(lo + span, hi_b))
    lo = np.minimum(lo, np.maximum(hi - span, lo_b))
    return 10.0 ** lo, 10.0 ** hi


def run_doe_zoom(cfg: dict, scout_jsons: dict[str, str], out_csv: str, out_json: str) -> None:
    """The zoomed second DOE: the same design in :func:`zoom_box` around the states' surface optima."""
    names = parameter_names(cfg)
    optima = {s: io.read_json(p)["surface_optimum"] for s, p in scout_jsons.items()}
    lo, hi = zoom_box(cfg, optima)
    sheet = doe_sheet(cfg, lo, hi)
    io.write_json(out_json, {"names": names, "lower": lo.tolist(), "upper": hi.tolist(),
                             "half_width_decades": zoom_half_width(cfg),
                             "first_stage_optima": optima})
    io.write_csv(sheet, out_csv)
    _log("doe zoom: " + ", ".join(f"{n} {a:.3g}..{b:.3g}" for n, a, b in zip(names, lo, hi))
         + f"; {len(sheet)} points -> {out_csv}")


def sheet_theta(sheet_csv: str, point: str, names: list[str]) -> dict[str, float]:
    """Physical parameters (N/m^3) of one point of a DOE sample sheet."""
    import pandas as pd

    sheet = pd.read_csv(sheet_csv).set_index("point")
    if point not in sheet.index:
        from jointid.errors import DataError

        raise DataError(f"doe: point {point} is not in {sheet_csv} (points: {', '.join(sheet.index)})")
    return {n: float(sheet.loc[point, n]) for n in names}


# ------------------------------------------------------------------ modal
def solve_point(cfg: dict, model, theta: dict[str, float], n_modes: int | None = None, describe: bool = True,
                certify: bool = False):
    """Modal solve of the cached model at joint parameters ``theta`` (N/m^3); ``certify``: with a
    Sturm check of its completeness (``modes.sturm``, :func:`jointid.fe.modal.solve_model`).

    Returns ``(freqs_Hz, shapes at measuring points (n_labels, n_modes), description table, modes)``.
    """
    from jointid.fe.modal import solve_model
    from jointid.fe.model import base_coefficients

    s = cfg["solver"]
    kc, mc = base_coefficients(cfg, model, theta)
    modes = solve_model(model, kc, mc, n_modes or s["n_modes"], shift_Hz=s["shift_Hz"], backend=s["backend"],
                        certify=certify)
    shapes = model.probe @ modes.phi
    desc = None
    if describe:
        from jointid.fe.describe import describe_modes

        desc = describe_modes(model, modes.phi, kc, mc)
    return modes.freqs_Hz, shapes, desc, modes


def run_modal(cfg: dict, matrices: str, theta: dict[str, float], out_npz: str, rom: str | None = None) -> None:
    """Modes at one DOE point -> ``out_npz`` (freqs_Hz, shapes, labels, description, strain_joints, theta).

    ``solver.method``: ``full`` (default) solves the FE model; ``rom`` evaluates the reduced-order
    model ``rom`` (written by :func:`run_rom`) and expands its modes to full DOF vectors for the
    mode descriptions.  Both write the same arrays.
    """
    import pandas as pd

    from jointid.fe.model import load_model
    from jointid.geometry.points import dof_labels

    model = load_model(matrices)
    if cfg["solver"].get("method", "full") == "rom":
        from jointid.fe.describe import describe_modes
        from jointid.errors import ConfigError
        from jointid.fe.model import base_coefficients
        from jointid.identification.rom import full_modes, load_rom

        if not rom:
            raise ConfigError("solver.method: rom needs the reduced-order model (rule rom, "
                              "results/rom/rom.npz) — build it with run_rom, or set solver.method: full")
        reduced = load_rom(rom)
        kc, mc = base_coefficients(cfg, model, theta)
        modes = full_modes(reduced, kc, mc, cfg["solver"]["n_modes"])
        freqs, shapes = modes.freqs_Hz, model.probe @ modes.phi
        desc = describe_modes(model, modes.phi, kc, mc)
    else:
        freqs, shapes, desc, _ = solve_point(cfg, model, theta)
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    io.write_npz(out_npz, freqs_Hz=freqs, shapes=shapes, labels=np.array(labels),
                 description=desc["description"].to_numpy().astype(str),
                 strain_joints=desc["strain_joints"].to_numpy(),
                 theta_names=np.array(list(theta)), theta=np.array(list(theta.values())))
    _log("modal: " + ", ".join(f"{f:.1f}" for f in freqs) + " Hz")


def run_rom(cfg: dict, matrices: str, sheet_csv: str, out_npz: str, out_json: str) -> dict:
    """Build the parametric reduced-order model once (``solver.method: rom``) with error control.

    Training: a full solve at the centre of the joint-parameter box (``solver.n_modes`` + 2 modes),
    then one block inverse iteration from the current Ritz vectors at each corner (one factorisation
    each, no Lanczos run; :func:`jointid.fe.rom.build_rom`).  Error control: candidate points (random interior ones and every point of the
    DOE sheet) are ranked by the residual indicator; the worst are solved in full, and the basis is
    enriched until the relative frequency error of every tracked mode (at or above
    ``solver.min_freq_Hz``) is at most ``solver.rom_tolerance``.  Writes the ROM with its basis
    (``out_npz``, :func:`jointid.fe.rom.load_rom`) and a summary (``out_json``: tolerance, achieved
    error, basis size, verification rounds); returns the summary.

    Raises
    ------
    ModelError
        If the tolerance is not met after the enrichment rounds.
    """
    import warnings

    import pandas as pd

    from jointid.errors import ModelError, NumericalWarning
    from jointid.fe.model import load_model
    from jointid.identification.rom_build import build_rom

    s = cfg["solver"]
    tol = float(s.get("rom_tolerance", 1e-4))
    model = load_model(matrices)
    sheet = pd.read_csv(sheet_csv)
    doe_x = sheet[[f"x_{n}" for n in parameter_names(cfg)]].to_numpy(float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)  # not verified: raised as an error below
        rom = build_rom(model, cfg, s["n_modes"], "corners", tol=tol, candidates=doe_x, progress=_log)
    rep = rom.report
    n_inverse = sum(1 for t in rep["training"] if t.get("how", "full solve") != "full solve")
    n_full = len(rep["training"]) - n_inverse + sum(len(r["points"]) for r in rep["rounds"])
    summary = {"n_dofs": int(model.n_dofs), "n_modes": rep["n_modes"], "n_train_modes": rep["n_train_modes"],
               "min_freq_Hz": float(s["min_freq_Hz"]), "tolerance": tol, "max_error": rep["max_error"],
               "verified": rep["verified"], "basis_size": rom.size, "n_full_solves": n_full,
               "n_inverse_iteration_points": n_inverse,
               "n_training_points": len(rep["training"]), "n_doe_candidates": int(len(doe_x)),
               "rounds": [{"round": r["round"], "basis_size": r["r"], "max_error": r["max_error"],
                           "added": r.get("added", 0),
                           "points": [{"theta": p["theta"], "max_error": p["max_error"]} for p in r["points"]]}
                          for r in rep["rounds"]],
               "coeff_range": rom.coeff_range}
    if not rep["verified"]:
        raise ModelError(f"rom: relative frequency error {rep['max_error']:.2e} at the verification points is "
                         f"above solver.rom_tolerance = {tol:.1e} after {len(rep['rounds'])} enrichment rounds "
                         f"(basis size {rom.size}) — raise solver.rom_tolerance, narrow joints.parameters, "
                         "or use solver.method: full")
    rom.save(out_npz)
    io.write_json(out_json, summary)
    _log(f"rom: basis {rom.size} vectors from {n_full} full solves and {n_inverse} inverse-iteration points "
         f"({model.n_dofs} DOFs); max relative "
         f"frequency error at the verification points {rep['max_error']:.2e} <= {tol:.1e} -> {out_npz}")
    return summary


def run_gather(sheet_csv: str, npz_paths: list[str], out_csv: str, out_npz: str) -> None:
    """Gather per-point modal results into one long table and one array file."""
    import pandas as pd

    sheet = pd.read_csv(sheet_csv)
    rows, freqs, shapes, descr = [], [], [], []
    for point, path in zip(sheet["point"], npz_paths):
        z = np.load(path)
        freqs.append(z["freqs_Hz"])
        shapes.append(z["shapes"])
        descr.append(z["description"])
        for j, f in enumerate(z["freqs_Hz"]):
            rows.append({"point": point, "mode": j + 1, "freq_Hz": float(f),
                         "description": str(z["description"][j]), "strain_joints": float(z["strain_joints"][j])})
    io.write_csv(pd.DataFrame(rows), out_csv)
    io.write_npz(out_npz, points=sheet["point"].to_numpy().astype(str), freqs_Hz=np.array(freqs),
                 shapes=np.array(shapes), labels=np.load(npz_paths[0])["labels"],
                 descriptions=np.array(descr))
    _log(f"gather: {len(npz_paths)} points -> {out_csv}")


# ------------------------------------------------------------------ surfaces
def tracked_band(cfg: dict) -> tuple[float, float]:
    """Modes of the reference point inside this band are tracked and fitted (Hz)."""
    return float(cfg["solver"]["min_freq_Hz"]), 1.25 * float(cfg["harmonic"]["band_Hz"][1])


def run_fit_surface(cfg: dict, sheet_csv: str, arrays_npz: str, out_json: str, out_csv: str,
                    box_json: str | None = None) -> None:
    """Track the modes through one DOE and fit the surfaces (``box_json``: the zoomed DOE's box)."""
    import pandas as pd

    from jointid.identification.updating import fit_surfaces

    sheet = pd.read_csv(sheet_csv)
    z = np.load(arrays_npz)
    descr = z["descriptions"]
    names = parameter_names(cfg)
    doc, diag = fit_surfaces(sheet, z["freqs_Hz"], z["shapes"], descr, names, tracked_band(cfg),
                             kind=cfg["surface"]["kind"])
    if box_json:  # the zoomed second DOE
        box = io.read_json(box_json)
        doc["lower"], doc["upper"], doc["stage"] = list(box["lower"]), list(box["upper"]), "zoom"
    else:
        doc["lower"], doc["upper"] = [b.tolist() for b in parameter_bounds(cfg)]
        doc["stage"] = "global"
    io.write_json(out_json, doc)
    io.write_csv(diag, out_csv)
    worst = diag["verify_max_error_pct"].max()
    _log(f"surface: {len(doc['tracked_modes'])} tracked modes, worst verification error {worst:.3f} %")
    limit = cfg["surface"]["max_verification_error_pct"]
    if worst > limit:
        import warnings

        from jointid.errors import NumericalWarning

        warnings.warn(f"surface: verification error {worst:.2f} % exceeds "
                      f"surface.max_verification_error_pct = {limit} %; the final FE verification "
                      "shows its effect on the identified frequencies", NumericalWarning)


# ------------------------------------------------------------------ identification
AMBIGUOUS_DCHI2 = 4.0  # pairings closer than this in summed chi-square are reported as alternatives


def _measured(cfg: dict, state: str, pts):
    """``(frequencies, shapes or None, frequency uncertainty in %)`` of one state's measured modes."""
    from jointid.config.datasets import dataset_folder
    from jointid.data.dataset import read_dataset
    from jointid.geometry.points import dof_labels

    from jointid.correlate.pairing import below_band
    from jointid.errors import DataError

    ds = read_dataset(dataset_folder(cfg, state), measuring_points=pts)
    low = below_band(ds.name, {state: ds.freqs(state)}, float(cfg["solver"]["min_freq_Hz"]))
    if low:
        raise DataError(low)
    shapes = None
    if ds.shapes is not None and state in set(ds.shapes["state"]):
        shapes = ds.shape_matrix(state, dof_labels(pts))
    sigma_pct = ds.conditions.get("frequency_uncertainty_pct", cfg["identify"]["frequency_uncertainty_pct"])
    return ds.freqs(state), shapes, float(sigma_pct)


def _pairing_notes(doc: dict, state: str, states: list[str], shared, info: dict, rule: str) -> list[str]:
    """Warnings on the pairing of frequency-only states: competing pairings of about equal fit, and
    the pairing the other rule (``identify.pairing``) would choose."""
    tm = lambda p: [doc["tracked_modes"][j] for j in p]  # noqa: E731
    own = info[state]["own"]
    k = len(doc["names"])
    if rule == "shared":
        chi2 = {tuple(c["pairing"]): c["chi2"] for c in info["candidates"]}
        dof = max(1, sum(len(own) - k for _ in states))
        chosen, what = tuple(shared), "over all states"
    else:
        chi2 = {tuple(c["pairing"]): c["chi2_by_state"][state] for c in info["candidates"]}
        dof = max(1, len(own) - k)
        chosen, what = tuple(own), "in this state"
    best = chi2[chosen]
    # chi2 scaled by its value per degree of freedom when the best fit is itself poor (then a model
    # error, not the noise, sets the scatter)
    scale = max(1.0, best / dof)
    close = sorted((v, p) for p, v in chi2.items() if p != chosen and (v - best) / scale < AMBIGUOUS_DCHI2)
    notes = []
    if close:
        notes.append(f"ambiguous pairing: besides tracked modes {tm(chosen)} (chi2 {best:.1f} {what}, {dof} "
                     "degrees of freedom) also " + "; ".join(f"tracked modes {tm(p)} (chi2 {v:.1f})" for v, p in close)
                     + f" fit within delta chi2 < {AMBIGUOUS_DCHI2:g}" + (f" (scaled by chi2/dof = {scale:.1f})"
                                                                          if scale > 1 else "")
                     + ": frequencies alone cannot tell them apart; measured shapes would")
    if list(shared) != own:
        if rule == "shared":
            notes.append(f"on its own this state would pair its measured modes with tracked modes {tm(own)} "
                         f"instead of {tm(shared)}: one pairing for all states ({', '.join(states)}) fits them "
                         "best together (identify.pairing: shared)")
        else:
            diff = [i + 1 for i, (a, b) in enumerate(zip(own, shared)) if a != b]
            notes.append(f"measured mode(s) {', '.join(map(str, diff))} pair with other tracked modes here "
                         f"({tm(own)}) than one pairing shared by all states would ({tm(shared)}): either the "
                         "modes swap order between the states or a pairing is off (identify.pairing: shared "
                         "forces one)")
    return notes


def run_identify(cfg: dict, state: str, surface_json: str, points_csv: str, out_json: str,
                 matrices: str | None = None, rom: str | None = None, states: list[str] | None = None,
                 edge_matrices: list[str] | None = None) -> None:
    """Identify one state's joint parameters: multistart on the surfaces, then the polish.

    The polish (``identify.fe_polish``) runs on the full FE model (``matrices``), or on the verified
    reduced-order model ``rom`` when one is given (``solver.method: rom``; the verify stage then
    checks the result with a full solve).  With ``states`` (all states of the run) and frequencies
    alone in every one of them, in equal numbers, ``identify.pairing: shared`` pairs the measured
    modes with the same tracked modes in every state (:func:`jointid.identification.updating.identify_states_jointly`)
    and the polish follows those modes by shape; ``independent`` (default) pairs each state by its
    own frequencies and re-pairs at every polish iterate.  Either way the notes name competing
    pairings and the other rule's choice.  With ``edge_matrices`` (``mesh.extrapolate_edges``: the
    models with one and two more edge levels) the polish is repeated on mesh-extrapolated frequencies
    (:mod:`jointid.fe.extrapolate`) until their factors settle (:func:`_extrapolated_polish`).
    """
    import pandas as pd

    from jointid.identification.updating import identify_state, identify_states_jointly

    doc = io.read_json(surface_json)
    pts = pd.read_csv(points_csv)
    f_meas, shapes, sigma_pct = _measured(cfg, state, pts)
    ic = cfg["identify"]
    weights = np.asarray(ic["weights"], float) if ic.get("weights") else None
    lower, upper = np.array(doc["lower"]), np.array(doc["upper"])
    zoom = doc.get("stage") == "zoom"
    rule = ic.get("pairing", "independent")
    shared, joint_info, pair_msgs = None, None, []
    if states and len(states) > 1 and state in states and shapes is None:
        others = {s: _measured(cfg, s, pts) for s in states}
        if all(o[1] is None for o in others.values()) and len({len(o[0]) for o in others.values()}) == 1:
            shared, joint_info = identify_states_jointly(
                doc, {s: o[0] for s, o in others.items()}, lower, upper, weights=weights,
                n_starts=ic["n_starts"], seed=ic["seed"], sigma_rel={s: o[2] / 100 for s, o in others.items()})
            pair_msgs = _pairing_notes(doc, state, states, shared, joint_info, rule)
    fixed = shared if rule == "shared" else None
    res, pairing, msgs = identify_state(doc, f_meas, lower, upper, meas_shapes=shapes, weights=weights,
                                        n_starts=ic["n_starts"], seed=ic["seed"], sigma_rel=sigma_pct / 100,
                                        pairing=fixed)
    msgs += pair_msgs
    if len(f_meas) <= len(doc["names"]):
        msgs.insert(0, f"{len(f_meas)} measured frequencies for {len(doc['names'])} identified parameters: "
                    + ("underdetermined, the values are one of many that fit equally well"
                       if len(f_meas) < len(doc["names"]) else "no residual degree of freedom is left")
                    + " and the intervals mean little — measure more modes, or fix parameters (joints.fixed)")
    if zoom:  # an edge of the zoomed box is no bound of the parameters: the FE polish may pass it
        msgs = [m for m in msgs if not any(m.startswith(f"{n} sits on its") for n in doc["names"])]
    surface_theta = np.asarray(res.theta, float)
    theta, ci_lo, ci_hi = surface_theta, res.ci_lower, res.ci_upper
    f_final, polish, edge = res.f_model, None, None
    if edge_matrices and not (matrices and ic.get("fe_polish", True)):
        msgs.append("mesh.extrapolate_edges needs identify.fe_polish: the frequencies fitted are those of the "
                    "base mesh")
    if matrices and cfg["identify"].get("fe_polish", True):
        b_lo, b_hi = parameter_bounds(cfg)
        polish = _polish(cfg, doc, matrices, surface_theta, pairing, f_meas, weights, sigma_pct / 100, b_lo, b_hi,
                         repair=shapes is None and fixed is None, rom=rom)
        if edge_matrices:
            edge, polish = _extrapolated_polish(cfg, state, doc, matrices, edge_matrices, polish, pairing, f_meas,
                                                weights, sigma_pct / 100, b_lo, b_hi,
                                                repair=shapes is None and fixed is None, rom=rom)
        theta, f_final = polish["theta"], polish["f_fe"]
        sd = np.sqrt(np.clip(np.diag(polish["cov_log10"]), 0, None))
        ci_lo, ci_hi = theta * 10 ** (-1.96 * sd), theta * 10 ** (1.96 * sd)
        for n in polish["on_bound"]:
            msgs.append(f"{n} sits on a bound of joints.parameters.{n} after the FE polish — widen the bounds")
        skipped = polish["unpaired_in_band_Hz"]
        if skipped:
            msgs.append(f"{len(skipped)} model mode(s) inside the measured band ("
                        + ", ".join(f"{f:.0f}" for f in skipped) + " Hz) have no measured partner: "
                        + ("the frequency-only pairing skipped them. Either the test missed them (check that "
                           "the excitation and measuring points could see them) or the reconstruction is off; "
                           "measured shapes would make the pairing unambiguous (MAC)" if shapes is None else
                           "the measured shapes pair with other model modes; check whether the test could "
                           "have missed them"))
    if zoom:
        out_of_box = [f"{n} = {t:.3g} (box {a:.3g}..{b:.3g})" for n, t, a, b in zip(doc["names"], theta, lower, upper)
                      if not a * (1 - 1e-9) <= t <= b * (1 + 1e-9)]
        if out_of_box:
            msgs.append("the optimum lies outside the zoomed DOE box, where its surfaces extrapolate: "
                        + "; ".join(out_of_box) + " — raise doe.zoom.half_width_decades")
        elif polish is None and res.on_bound:
            msgs.append(f"{', '.join(res.on_bound)} on an edge of the zoomed DOE box: the optimum may lie beyond "
                        "it — raise doe.zoom.half_width_decades or enable identify.fe_polish")
    areas = io.read_json(points_csv.replace("measuring_points.csv", "summary.json"))["contact_area_per_carriage_m2"]
    per_carriage = {}
    for n, th, lo, hi in zip(doc["names"], theta, ci_lo, ci_hi):
        a = areas.get(_face_of(cfg, n), 0.0)
        per_carriage[n.replace("_N_per_m3", "_per_carriage_N_per_um")] = {
            "value": th * a * 1e-6, "ci95_low": lo * a * 1e-6, "ci95_high": hi * a * 1e-6}
    out = {"state": state, "parameters": {n: {"value": th, "ci95_low": lo, "ci95_high": hi}
                                          for n, th, lo, hi in zip(doc["names"], theta, ci_lo, ci_hi)},
           "surface_optimum": {n: float(t) for n, t in zip(doc["names"], surface_theta)},
           "surface_stage": doc.get("stage", "global"),
           "surface_box": {n: [float(a), float(b)] for n, a, b in zip(doc["names"], lower, upper)},
           "fe_polish": None if polish is None else {
               "on": "rom" if rom else "fe",
               "unpaired_in_band_Hz": polish["unpaired_in_band_Hz"],
               "iterations": polish["iterations"], "cost_history": polish["cost_history"],
               "f_fe_Hz": polish["f_fe"], "mac": polish["mac"]},
           "edge_extrapolation": edge,
           "per_carriage": per_carriage, "x_coded": res.x_coded, "pairing_tracked_mode": [
               doc["tracked_modes"][j] for j in pairing], "pairing_columns": pairing,
           "paired_by": "mac" if shapes is not None else ("frequency, shared by all states" if fixed is not None
                                                          else "frequency"),
           "joint_pairing": joint_info,
           "f_meas_Hz": f_meas, "f_surface_Hz": res.f_model,
           "residual_pct": 100 * (np.asarray(f_final) - f_meas) / f_meas,
           "cost": res.cost, "condition_number": res.condition_number,
           "weak_combination": res.weak_combination,
           "on_bound": res.on_bound if polish is None else polish["on_bound"],
           "n_starts_agreeing": res.n_starts_agreeing, "warnings": msgs,
           "frequency_uncertainty_pct": sigma_pct}
    io.write_json(out_json, out)
    _log(f"identify[{state}]: " + ", ".join(f"{n} = {t:.4g}" for n, t in zip(doc["names"], theta))
         + f"; max |error| {np.abs(out['residual_pct']).max():.2f} %")
    for m in msgs:
        _log("warning: " + m)


def _polish(cfg, doc, matrices, theta0, pairing, f_meas, weights, sigma_rel, lower, upper, repair=False,
            rom=None, correction=None):
    """Gauss-Newton refinement of the surface optimum on the full FE model (or the ROM file ``rom``)."""
    from jointid.fe.model import load_model

    ref = np.asarray(doc["ref_shapes"])[:, pairing]
    if rom:
        from jointid.identification.rom import load_rom

        model = load_rom(rom)
    else:
        model = load_model(matrices)
    return polish_on_model(cfg, model, doc["names"], theta0, f_meas, ref, lower, upper,
                           weights=weights, sigma_rel=sigma_rel, repair=repair, correction=correction)


EXTRAPOLATION_PASSES = 3  # polishes on extrapolated frequencies, each with factors taken at the last optimum
EXTRAPOLATION_SETTLED = 2e-3  # the factors have settled once their first-order change over a polish is below this


def _extrapolated_polish(cfg, state, doc, matrices, edge_matrices, polish, pairing, f_meas, weights, sigma_rel,
                         lower, upper, *, repair, rom):
    """The polish again on mesh-extrapolated frequencies, until their factors are those of its optimum.

    The factors are taken at the current optimum (first the base mesh's), with their first-order
    dependence on the parameters, and the polish is repeated with them.  Should they change by more
    than ``EXTRAPOLATION_SETTLED`` (relative, to first order) over the polish's step, where their
    second-order change might matter, they are taken again at the new optimum (at most
    ``EXTRAPOLATION_PASSES`` passes).  Returns ``(record for params.json, the last polish)``.
    """
    from jointid.fe.extrapolate import FrequencyCorrection
    from jointid.fe.model import load_model

    say = lambda m: _log(f"identify[{state}]: {m}")  # noqa: E731
    models = [load_model(p) for p in (matrices, *edge_matrices)]
    theta_mesh = dict(zip(doc["names"], map(float, polish["theta"])))
    passes = []
    for k in range(EXTRAPOLATION_PASSES):
        at = np.asarray(polish["theta"], float)
        say(f"mesh extrapolation over the edge levels at {'the base-mesh optimum' if k == 0 else 'the new optimum'}")
        lim = edge_limit_at(cfg, models, dict(zip(doc["names"], map(float, at))), log=say, sensitivities=True)
        shown = [i for i in range(lim.limit_Hz.size) if lim.levels_Hz[0, i] >= cfg["solver"]["min_freq_Hz"]]
        say("extrapolated: " + ", ".join(f"{lim.levels_Hz[0, i]:.1f}->{lim.limit_Hz[i]:.1f} Hz" for i in shown))
        say("polish on the extrapolated frequencies")
        polish = _polish(cfg, doc, matrices, at, pairing, f_meas, weights, sigma_rel, lower, upper,
                         repair=repair, rom=rom, correction=FrequencyCorrection.from_limit(lim, at))
        moved = float(np.max(np.abs(polish["theta"] / at - 1)))
        drift = float(np.max(np.abs(lim.slope[shown] @ np.log10(polish["theta"] / at))))
        passes.append({"factors_at": dict(zip(doc["names"], map(float, at))), "max_parameter_change": moved,
                       "max_factor_change_first_order": drift})
        say(f"pass {k + 1}: the polish moved the parameters by at most {100 * moved:.2f} %, the factors by "
            f"{100 * drift:.3f} % (first order)")
        if drift < EXTRAPOLATION_SETTLED:
            break
    else:
        say(f"warning: the factors did not settle in {EXTRAPOLATION_PASSES} passes (last change {100 * drift:.3f} %)")
    odd = [f"{lim.levels_Hz[0, i]:.0f} Hz ({lim.status[i]})" for i in shown
           if lim.status[i] in ("not asymptotic", "lost")]
    if odd:
        say("kept the finest mesh's frequency (no geometric sequence): " + ", ".join(odd))
    record = {"theta_base_mesh": theta_mesh, "n_dofs": lim.n_dofs, "passes": passes,
              "modes": lim.table().to_dict(orient="list"), "not_extrapolated": odd}
    return record, polish


def polish_on_model(cfg: dict, model, names: list[str], theta0, f_meas, ref_shapes, lower, upper, *,
                    weights=None, sigma_rel: float = 0.01, repair: bool = False, max_iter: int = 8, log=None,
                    correction=None):
    """FE polish (:func:`jointid.identification.updating.fe_polish`) of joint parameters ``names`` on ``model``.

    ``model`` is the full FE model (:class:`jointid.fe.fem.Model`) or a reduced-order model
    (:class:`jointid.fe.rom.ROM`, evaluated in its generalised coordinates, where the sensitivities
    ``y^T Kr_i y`` are exact for the reduced model).  On the full model the iterates are solved by a
    :class:`jointid.fe.reduced.ReducedSolver` started at ``theta0`` (the exact modes there and their
    responses to each parameter, enriched wherever a Ritz pair's full-space residual says its
    eigenvalue is off by more than 1e-6): full-FE answers for one factorisation instead of one per
    iterate.  ``ref_shapes`` ``(n_labels, n_measured)`` are the shapes the measured modes follow by
    MAC; with ``repair`` (frequency-only data) the modes are re-paired by frequency at every iterate
    instead.  ``correction`` (:class:`jointid.fe.extrapolate.FrequencyCorrection`) scales each mode's
    frequency by the mesh-extrapolation factor of the mode it continues.
    """
    from jointid.fe.model import base_coefficients, joint_terms
    from jointid.identification.updating import fe_polish

    from jointid.identification.rom import ROM

    jt = joint_terms(cfg["joints"])
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    n_modes = cfg["solver"]["n_modes"]
    if isinstance(model, ROM):
        reduced_terms = dict(zip(model.k_names, model.k_terms))

        def solve(theta):
            freqs, shapes, y = model.solve_theta(dict(zip(names, theta)), n_modes, return_coords=True)
            return freqs, shapes, y, reduced_terms
    else:
        from jointid.fe.reduced import ReducedSolver

        kc0, mc0 = base_coefficients(cfg, model, dict(zip(names, theta0)))
        rs = ReducedSolver(model, kc0, mc0, n_modes, [(t, {}) for t in terms], shift_Hz=cfg["solver"]["shift_Hz"],
                           backend=cfg["solver"]["backend"])

        def solve(theta):
            sol = rs.solve(*base_coefficients(cfg, model, dict(zip(names, theta))), n_modes)
            return sol.freqs_Hz, sol.shapes, rs.full_phi(sol), model.stiffness

    if correction is not None:
        solve = _corrected(solve, correction)
    return fe_polish(solve, theta0, names, lower, upper, f_meas, ref_shapes, terms, weights=weights,
                     sigma_rel=sigma_rel, max_iter=max_iter, log=log or _log,
                     repair_min_Hz=cfg["solver"]["min_freq_Hz"] if repair else None)


def _corrected(solve, correction):
    """``solve`` with each mode's frequency scaled by its mesh-extrapolation factor (in ascending order).

    A factor adds its own ``d ln c / d log10 theta`` to the mode's ``d ln f / d log10 theta``, which
    the polish gets as a fifth return value; :func:`jointid.identification.updating.log_jacobian` computes the
    mesh's part as ``phi^T K' phi / (2 lambda)`` from the frequency it is given, so ``phi`` is scaled
    by the same factor to keep that part exact.
    """
    def solve_corrected(theta):
        freqs, shapes, phi, stiff = solve(theta)
        c, grad = correction.factors(shapes, theta)
        order = np.argsort(freqs * c, kind="stable")
        out = (freqs * c)[order], shapes[:, order], (phi * c)[:, order], stiff
        return out if grad is None else (*out, grad[order])  # + the factors' own d ln / d log10 theta

    return solve_corrected


def edge_limit_at(cfg: dict, models: list, theta: dict[str, float], log=None, base=None,
                  sensitivities: bool = False):
    """:class:`jointid.fe.extrapolate.EdgeLimit` of the modes of ``models[0]`` at ``theta``; ``models``:
    the base mesh and the meshes with one and two more edge levels (a few more modes are solved on
    those, so that the highest base modes find their partner), each a model or a function that
    builds one (built when its turn comes and dropped after its solve); ``base``: the base mesh's
    ``(freqs_Hz, shapes)`` at ``theta`` when already solved; ``sensitivities``: with the factors'
    first-order dependence on ``theta`` (exact modal sensitivities on each mesh)."""
    from jointid.fe.extrapolate import edge_limit
    from jointid.fe.model import joint_terms
    from jointid.identification.updating import log_jacobian

    names = list(theta)
    jt = joint_terms(cfg["joints"])
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    solves = []
    for k, model in enumerate(models):
        model = model() if callable(model) else model
        if k == 0 and base is not None:
            solves.append((*base, model.n_dofs))
            continue
        f, s, _, modes = solve_point(cfg, model, theta, n_modes=cfg["solver"]["n_modes"] + (2 if k else 0),
                                     describe=False)
        J = (log_jacobian(model.stiffness, modes.phi, modes.omega2, terms, np.array([theta[n] for n in names]))
             if sensitivities else None)
        solves.append((f, s, model.n_dofs, J))
        if log:
            log(f"edge level +{k}: {model.n_dofs} DOFs solved")
        del model
    return edge_limit(solves)


def _face_of(cfg: dict, name: str) -> str:
    from jointid.fe.model import joint_terms

    terms = joint_terms(cfg["joints"])[name]
    return "+".join(sorted({t.split("_")[1] for t in terms}))


def run_verify(cfg: dict, state: str, params_json: str, surface_json: str, matrices: str, out_csv: str,
               edge_matrices: list[str] | None = None) -> None:
    """Full FE re-solve at the identified parameters: the tables' simulated frequencies.

    With ``edge_matrices`` (``mesh.extrapolate_edges``) the simulated frequencies are the
    mesh-extrapolated ones at these parameters (:mod:`jointid.fe.extrapolate`, solved afresh here), and
    ``simulation_mesh_Hz`` keeps the base mesh's; the surfaces are compared with the base mesh.
    """
    import pandas as pd

    from jointid.fe.model import load_model
    from jointid.identification.updating import verify_pairing

    par = io.read_json(params_json)
    doc = io.read_json(surface_json)
    theta = {n: v["value"] for n, v in par["parameters"].items()}
    model = load_model(matrices)
    freqs, shapes, desc, modes = solve_point(cfg, model, theta, certify=True)
    _log(f"verify[{state}]: {modes.sturm.describe() if modes.sturm else 'no Sturm check (one mode)'}")
    f_meas = np.asarray(par["f_meas_Hz"])
    f_all, lim = freqs, None
    if edge_matrices:
        lim = edge_limit_at(cfg, [model, *map(load_model, edge_matrices)], theta,
                            log=lambda m: _log(f"verify[{state}]: {m}"), base=(freqs, shapes))
        f_all = lim.limit_Hz
    if par.get("paired_by") == "frequency":  # the polish's rule: re-paired by frequency at its optimum
        from jointid.correlate.mac import mac
        from jointid.correlate.pairing import pair_by_frequency

        cand = np.flatnonzero(f_all >= cfg["solver"]["min_freq_Hz"])
        index = cand[pair_by_frequency(f_meas, f_all[cand])]
        ref = np.asarray(doc["ref_shapes"])[:, np.asarray(par["pairing_columns"])]
        macs = np.array([float(mac(ref[:, i], shapes[:, j])[0, 0]) for i, j in enumerate(index)])
    else:
        index, macs = verify_pairing(doc, np.asarray(par["pairing_columns"]), shapes)
    paired = np.clip(index, 0, None)
    fe = np.where(index >= 0, freqs[paired], np.nan)
    sim, extra = fe, {}
    if lim is not None:
        sim = np.where(index >= 0, lim.limit_Hz[paired], np.nan)
        extra = {"simulation_mesh_Hz": fe, "edge_factor": np.where(index >= 0, lim.factor[paired], np.nan),
                 "edge_ratio": np.where(index >= 0, lim.ratio[paired], np.nan),
                 "edge_status": [lim.status[i] if i >= 0 else "" for i in index]}
    rows = pd.DataFrame({
        "order": np.arange(1, len(f_meas) + 1), "experimental_Hz": f_meas, "simulation_Hz": sim,
        "relative_error_pct": 100 * (sim - f_meas) / f_meas, **extra,
        "surface_Hz": par["f_surface_Hz"], "surface_vs_fe_pct": 100 * (np.asarray(par["f_surface_Hz"]) - fe) / fe,
        "fe_mode": index + 1, "mac_to_tracked": macs,
        "description": [desc["description"][i] if i >= 0 else "unpaired" for i in index],
        "strain_joints": [float(desc["strain_joints"][i]) if i >= 0 else np.nan for i in index]})
    io.write_csv(rows, out_csv)
    _log(f"verify[{state}]: FE max |error| {np.nanmax(np.abs(rows.relative_error_pct)):.2f} %, "
         f"surface vs FE (base mesh) max {np.nanmax(np.abs(rows.surface_vs_fe_pct)):.2f} %")
    if edge_matrices and par.get("fe_polish"):
        # the identification's last polish scaled by factors taken at its previous optimum; here they are fresh
        drift = 100 * (sim / np.asarray(par["fe_polish"]["f_fe_Hz"]) - 1)
        _log(f"verify[{state}]: extrapolated frequencies vs the identification's: max "
             f"{np.nanmax(np.abs(drift)):.3f} % (its factors come from its previous optimum, to first order)")


# ------------------------------------------------------------------ tables
def run_tables(verify_csvs: dict[str, str], paper_csv: str, outputs: dict[str, str]) -> None:
    """Tables 2 and 3: our FE-verified frequencies beside the paper's."""
    import pandas as pd

    from jointid.reporting.tables import frequency_table, markdown_table

    paper = pd.read_csv(paper_csv)
    for state, path in verify_csvs.items():
        tab = frequency_table(pd.read_csv(path), paper, state)
        io.write_csv(tab, outputs[state])
        io.write_text(outputs[state].replace(".csv", ".md"), markdown_table(tab, state))
        _log(f"table[{state}]: max |error| {tab.relative_error_pct.abs().max():.2f} % "
             f"(paper {tab.paper_relative_error_pct.abs().max():.1f} %)")
