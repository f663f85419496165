"""(f) Identified joint parameters on a refined mesh: do they move by less than 2 %?

Takes the identified parameters of every state from ``results/identify/<state>/params.json`` (run
``snakemake -j2`` first), re-identifies them on the first refined mesh of benchmark (e) (cells halved
through the thickness and in the joint zone, where the mesh error lives) by the same FE Gauss-Newton polish with frequency re-pairing that the
``identify`` rule ends with, and prints the change of each parameter and of the max frequency error.
"""

from __future__ import annotations

import json

import numpy as np

from .bench_e_convergence import _references
from .common import ROOT, Result
from jointid.config.typed import ModelSpec

LIMIT_PCT = 2.0


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    from jointid.config import load_config
    from jointid.fe.model import build_model
    from jointid.identification.polish import PolishFit, polish_on_model

    res = Result("f")
    base = {"mesh": {"element": "hex2", "max_cell_size_m": 0.12, "height_cell_fraction": 1.0,
                     "joint_cell_fraction": 1.0}} if quick else {}
    label, over = _references(base)[0]
    cfg = load_config(ROOT / "config.yaml", overrides=over)
    model = build_model(ModelSpec.from_config(cfg))
    names = list(cfg["joints"]["parameters"])
    lo = np.array([cfg["joints"]["parameters"][n]["lower"] for n in names])
    hi = np.array([cfg["joints"]["parameters"][n]["upper"] for n in names])
    data = {"refined": label, "n_dofs": model.n_dofs, "states": {}}
    for state in cfg["states"]:
        path = ROOT / "results" / "identify" / state / "params.json"
        if not path.exists():
            res.notes.append(f"{path.relative_to(ROOT)} missing — run `snakemake -j2` first")
            continue
        doc = json.loads(path.read_text())
        theta0 = np.array([doc["parameters"][n]["value"] for n in names])
        f_meas = np.asarray(doc["f_meas_Hz"], float)
        n_lab = model.probe.shape[0]
        out = polish_on_model(ModelSpec.from_config(cfg), model, names, theta0,
                              PolishFit(f_meas, np.zeros((n_lab, len(f_meas))), lo, hi, repair=True), max_iter=3,
                              log=lambda m, state=state: print(f"[f] {state}: {m.strip()}", flush=True))
        err_default = float(np.abs(doc["residual_pct"]).max())
        err_refined = float(np.abs(100 * (out["f_fe"] - f_meas) / f_meas).max())
        changes = 100 * (out["theta"] / theta0 - 1)
        for n, t0, t1, c in zip(names, theta0, out["theta"], changes):
            res.add(f"{state}: {n}", f"{t0:.4g} -> {t1:.4g} N/m^3 ({c:+.2f} %)", f"|change| < {LIMIT_PCT} %",
                    abs(c) < LIMIT_PCT)
        res.add(f"{state}: max |frequency error|", f"{err_default:.2f} % -> {err_refined:.2f} %")
        data["states"][state] = {"theta_default": theta0.tolist(), "theta_refined": out["theta"].tolist(),
                                 "change_pct": changes.tolist(), "max_err_default_pct": err_default,
                                 "max_err_refined_pct": err_refined}
    res.notes.append(f"refined mesh: {label}, {model.n_dofs} DOFs; parameters re-identified by the FE polish "
                     "from the default-mesh optimum")
    res.data = data
    return res
