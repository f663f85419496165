"""Rule ``mesh``: build and cache the FE model of the rig.

Imports of the numerical modules are inside the functions: every workflow job is a fresh Python
process and loads only what its stage uses, and the Snakefile imports the stages at parse time without
loading the FE code.  Rule ``mesh``'s config keys and input files are
:func:`jointid.config.snakefile.mesh_keys` and :func:`~jointid.config.snakefile.mesh_inputs`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.typed import ModelSpec


def run_mesh(spec: ModelSpec, matrices: str, points_csv: str, vtu: str | None = None,
             summary_json: str | None = None) -> None:
    """Build and cache the model matrices, the measuring-point table, the model summary
    (:func:`model_summary`; ``summary_json``, by default ``summary.json`` beside ``points_csv``) and a
    VTK file of the mesh (``spec``: the model's :class:`~jointid.config.typed.ModelSpec`)."""
    from jointid.fe.model import save_model

    model = mesh_model(spec)
    save_model(model, matrices)
    pts = points_table(model)
    io.write_csv(pts, points_csv)
    io.write_json(summary_json or str(points_csv).replace("measuring_points.csv", "summary.json"),
                  model_summary(model))
    if vtu:
        from jointid.fe.vtk import write_mesh_vtu

        write_mesh_vtu(model, vtu)
    log(f"mesh: wrote {matrices} ({model.n_dofs} DOFs), {points_csv}")


def mesh_model(spec: ModelSpec, progress=log):
    """Rule ``mesh``'s model of ``spec`` (:class:`jointid.fe.fem.Model`), with its fill-reducing ordering."""
    from jointid.fe.model import edge_level_model

    return edge_level_model(spec, 0, progress=progress)


def points_table(model):
    """The measuring points of ``model`` (rule ``mesh``'s ``measuring_points.csv``: ``point, x_m, y_m, z_m`` ...)."""
    import pandas as pd

    return pd.DataFrame(model.meta["points"])


def model_summary(model) -> dict:
    """Sizes and areas of the model (for per-carriage conversions and reports): ``n_dofs,
    n_elements, element, support, contact_area_m2`` (m^2 per face), ``contact_area_per_carriage_m2``,
    ``motor_mass_kg``, ``dims_m``, ``carriage_centres_m``."""
    m = model.meta
    if m.get("kind") == "mesh":  # a joint layer is the unit: its whole area stands for "per carriage"
        return {"kind": "mesh", "n_dofs": m["n_dofs"], "n_elements": m["n_elements"], "element": m["element"],
                "support": m["support"], "contact_area_m2": m["contact_area_m2"],
                "contact_area_per_carriage_m2": _combined_areas(m["contact_area_m2"]),
                "bodies": m["bodies"], "source": m["source"]}
    per = {face: a / 4 for face, a in m["contact_area_m2"].items()}
    per["flank+top"] = per["top"] + per["flank"]
    return {"n_dofs": m["n_dofs"], "n_elements": m["n_elements"], "element": m["element"],
            "support": m["support"], "contact_area_m2": m["contact_area_m2"],
            "contact_area_per_carriage_m2": per, "motor_mass_kg": m["motor_mass_kg"],
            "dims_m": m["dims_m"], "carriage_centres_m": m["carriage_centres_m"]}


def _combined_areas(areas: dict[str, float]) -> dict[str, float]:
    """Areas of every joint and of every set of joints (keys ``a+b``, sorted), for a parameter
    acting on several layers."""
    from itertools import combinations

    names = sorted(areas)
    out = {}
    for k in range(1, min(len(names), 4) + 1):
        for combo in combinations(names, k):
            out["+".join(combo)] = float(sum(areas[n] for n in combo))
    return out
