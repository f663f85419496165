"""(i) The eigen-solver alone: block shift-invert Lanczos against single-vector ARPACK on one factor.

The default model at the default joint parameters, factorised once; then the lowest 12, 20 and 30
modes by each method (best of two), the time of the eigen-solve alone and how closely the two agree
(frequencies, and mass-normalised shapes with the same sign convention).  ``--quick``: the coarse
test mesh, where the workflow itself uses ARPACK (below ``jointid.fe.blocklanczos.MIN_DOFS``).
"""

from __future__ import annotations

from .common import COARSE, Result, fmt_s, run_worker


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    res = Result("i")
    out = run_worker("eigen", {"overrides": COARSE if quick else {}, "n_modes_list": [12, 20, 30]},
                     blas_threads=blas_threads)
    res.add(f"factorisation of K - sigma M ({out['n_free']} free DOFs)", fmt_s(out["t_factor_s"]))
    for c in out["cases"]:
        res.add(f"{c['n_modes']} modes: block Lanczos vs ARPACK (eigen-solve alone)",
                f"{fmt_s(c['t_block_s'])} vs {fmt_s(c['t_arpack_s'])} ({c['t_arpack_s'] / c['t_block_s']:.2f}x)")
        res.add(f"{c['n_modes']} modes: agreement (max relative difference)",
                f"frequencies {c['max_rel_freq_diff']:.1e}, shapes {c['max_shape_diff']:.1e}", "<= 1e-10 / 1e-8",
                bool(c["max_rel_freq_diff"] <= 1e-10 and c["max_shape_diff"] <= 1e-8))
    res.notes.append(f"{'coarse test mesh' if quick else 'default mesh'}; peak RSS {out['peak_rss_MB']:.0f} MB")
    res.data = out
    return res
