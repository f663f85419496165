"""(e) Mesh convergence: first 12 frequencies of the default model vs a once-refined mesh."""

from __future__ import annotations

import numpy as np

from .common import COARSE, Result
from .memo import solve

N_MODES = 12
LIMIT_PCT = 0.5


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    from jointid.modal import mac, pair_by_mac

    res = Result("e")
    base = COARSE if quick else {}
    refine = {"mesh": {**base.get("mesh", {}), "refine": 2}}
    a = solve(base, N_MODES, blas_threads=blas_threads, timeout=3600)
    b = solve(refine, N_MODES + 4, blas_threads=blas_threads, timeout=3600)  # margin for mode swaps
    m = mac(np.array(a["shapes"]), np.array(b["shapes"]))
    pairs = {r: (c, v) for r, c, v in pair_by_mac(m, 0.0)}
    worst = 0.0
    rows = []
    for i, f in enumerate(a["freqs_Hz"]):
        j, v = pairs.get(i, (i, float("nan")))
        g = b["freqs_Hz"][j]
        d = 100 * (f - g) / g
        worst = max(worst, abs(d))
        rows.append({"mode": i + 1, "freq_Hz": f, "refined_mode": j + 1, "refined_freq_Hz": g,
                     "diff_pct": d, "mac": v})
        res.add(f"mode {i + 1}", f"{f:8.1f} Hz vs {g:8.1f} Hz (refined mode {j + 1}, MAC {v:.3f}): {d:+.3f} %",
                f"|diff| <= {LIMIT_PCT} %", abs(d) <= LIMIT_PCT)
    res.add("worst of the first 12", f"{worst:.3f} %", f"<= {LIMIT_PCT} %", worst <= LIMIT_PCT)
    res.notes.append(f"{'coarse test mesh' if quick else 'default mesh'} ({a['n_dofs']} DOFs) vs refine: 2 "
                     f"({b['n_dofs']} DOFs), default joint parameters (geometric means of the bounds); "
                     "modes paired by MAC at the measuring points (positive diff: the default mesh is stiffer)")
    res.data = {"rows": rows, "default": {k: a[k] for k in ("n_dofs", "t_total_s", "peak_rss_MB")},
                "refined": {k: b[k] for k in ("n_dofs", "t_total_s", "peak_rss_MB")}}
    return res
