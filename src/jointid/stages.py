"""One function per workflow stage: read inputs, call the package, write outputs atomically.

The Snakemake scripts in ``workflow/scripts`` are adapters around these functions, and every stage
can be run from a plain Python session as well.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import io
from .describe import describe_modes
from .doe import design, to_physical, verification_points
from .modal import solve_modes
from .model import base_coefficients, build_model, load_model, save_model
from .points import dof_labels


def _log(msg: str) -> None:
    print(msg, flush=True)


# ------------------------------------------------------------------ mesh
def run_mesh(cfg: dict, matrices: str, points_csv: str, vtu: str | None = None) -> None:
    """Build and cache the model matrices, the measuring-point table and a VTK file of the mesh."""
    model = build_model(cfg, progress=_log)
    save_model(model, matrices)
    pts = pd.DataFrame(model.meta["points"])
    io.write_csv(pts, points_csv)
    if vtu:
        from .vtk import write_mesh_vtu

        write_mesh_vtu(model, vtu)
    _log(f"mesh: wrote {matrices} ({model.n_dofs} DOFs), {points_csv}")


# ------------------------------------------------------------------ doe
def parameter_names(cfg: dict) -> list[str]:
    return list(cfg["joints"]["parameters"])


def doe_sheet(cfg: dict) -> pd.DataFrame:
    """The DOE as a sample sheet: one row per FE solve (design points, then verification points).

    Columns: ``point, role, x_<param>`` (coded in [-1, 1] over log10 of the parameter) and
    ``<param>`` (physical, N/m^3).
    """
    names = parameter_names(cfg)
    d = cfg["doe"]
    X = design(d["design"], len(names), n_center=d["n_center"], n_samples=d.get("n_samples", 0),
               seed=d["seed"])
    V = verification_points(d["n_verification"], len(names), seed=d["seed"] + 1)
    lo = np.array([cfg["joints"]["parameters"][n]["lower"] for n in names])
    hi = np.array([cfg["joints"]["parameters"][n]["upper"] for n in names])
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


# ------------------------------------------------------------------ modal
def solve_point(cfg: dict, model, theta: dict[str, float], n_modes: int | None = None):
    """Modal solve of the cached model at joint parameters ``theta`` (N/m^3).

    Returns ``(freqs_Hz, shapes at measuring points (n_labels, n_modes), description table, modes)``.
    """
    s = cfg["solver"]
    kc, mc = base_coefficients(cfg, model, theta)
    modes = solve_modes(model.K(kc), model.M(mc), n_modes or s["n_modes"], shift_Hz=s["shift_Hz"],
                        fixed=model.fixed, backend=s["backend"])
    shapes = model.probe @ modes.phi
    desc = describe_modes(model, modes.phi, kc, mc)
    return modes.freqs_Hz, shapes, desc, modes


def run_modal(cfg: dict, matrices: str, theta: dict[str, float], out_npz: str) -> None:
    model = load_model(matrices)
    freqs, shapes, desc, _ = solve_point(cfg, model, theta)
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    io.write_npz(out_npz, freqs_Hz=freqs, shapes=shapes, labels=np.array(labels),
                 description=desc["description"].to_numpy().astype(str),
                 strain_joints=desc["strain_joints"].to_numpy(),
                 theta_names=np.array(list(theta)), theta=np.array(list(theta.values())))
    _log("modal: " + ", ".join(f"{f:.1f}" for f in freqs) + " Hz")


def run_gather(sheet_csv: str, npz_paths: list[str], out_csv: str, out_npz: str) -> None:
    """Gather per-point modal results into one long table and one array file."""
    sheet = pd.read_csv(sheet_csv)
    rows, freqs, shapes = [], [], []
    for point, path in zip(sheet["point"], npz_paths):
        z = np.load(path)
        freqs.append(z["freqs_Hz"])
        shapes.append(z["shapes"])
        for j, f in enumerate(z["freqs_Hz"]):
            rows.append({"point": point, "mode": j + 1, "freq_Hz": float(f),
                         "description": str(z["description"][j]), "strain_joints": float(z["strain_joints"][j])})
    io.write_csv(pd.DataFrame(rows), out_csv)
    io.write_npz(out_npz, points=sheet["point"].to_numpy().astype(str), freqs_Hz=np.array(freqs),
                 shapes=np.array(shapes), labels=np.load(npz_paths[0])["labels"])
    _log(f"gather: {len(npz_paths)} points -> {out_csv}")
