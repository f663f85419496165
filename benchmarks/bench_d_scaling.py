"""(d) Scaling of a full modal solve (build_model + 12 modes) with the number of DOFs."""

from __future__ import annotations

import numpy as np

from .common import Result, fmt_mb, fmt_s
from .memo import solve

# mesh.max_cell_size_m giving ~30k, 75k, 150k, 300k DOFs with the default rig (hex2, refine 1); the
# grid lines every part boundary needs keep the default rig above ~29k DOFs at any cell size
SIZES = {"30k": 0.09, "75k": 0.05, "150k": 0.036, "300k": 0.026}
QUICK = {"17k": 0.12, "40k": 0.06}
N_MODES = 12
LIMIT_GIB = 24.0


def fit_exponent(n: np.ndarray, t: np.ndarray) -> float:
    """Least-squares slope of log t over log n (t ~ n^p)."""
    return float(np.polyfit(np.log(n), np.log(t), 1)[0])


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    res = Result("d")
    rows = []
    for label, h in (QUICK if quick else SIZES).items():
        out = solve({"mesh": {"max_cell_size_m": h}}, N_MODES, blas_threads=blas_threads, timeout=3600)
        rows.append({"label": label, "max_cell_size_m": h, **{k: out[k] for k in (
            "n_dofs", "n_free", "t_assembly_s", "t_solve_s", "t_total_s", "peak_rss_MB", "backend")}})
        res.add(f"{out['n_dofs']} DOFs (max_cell_size_m {h})",
                f"{fmt_s(out['t_total_s'])} (assembly {fmt_s(out['t_assembly_s'])}, solve "
                f"{fmt_s(out['t_solve_s'])}), peak RSS {fmt_mb(out['peak_rss_MB'])}")
    n = np.array([r["n_dofs"] for r in rows], float)
    p_total = fit_exponent(n, np.array([r["t_total_s"] for r in rows]))
    p_solve = fit_exponent(n, np.array([r["t_solve_s"] for r in rows]))
    p_mem = fit_exponent(n, np.array([r["peak_rss_MB"] for r in rows]))
    res.add("fitted exponent t ~ DOFs^p", f"total {p_total:.2f}, solve {p_solve:.2f}, peak RSS {p_mem:.2f}",
            "reported")
    big = rows[-1]
    gib = big["peak_rss_MB"] / 1024
    res.add(f"largest ({big['n_dofs']} DOFs) peak RSS", f"{gib:.2f} GiB",
            f"<= {LIMIT_GIB:.0f} GiB" + (" at 300k" if not quick else ""), gib <= LIMIT_GIB if not quick else None)
    res.notes.append(f"each size in its own process; backend {big['backend']}; "
                     f"BLAS threads per process: {blas_threads or 'default'}")
    res.data = {"rows": rows, "exponent_total": p_total, "exponent_solve": p_solve, "exponent_rss": p_mem}
    return res
