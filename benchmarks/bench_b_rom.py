"""(b) Reduced-order model evaluation vs full modal solve: speed ratio and max frequency error."""

from __future__ import annotations

from .common import COARSE, Result, fmt_s, run_worker

N_MODES = 12


def run(quick: bool = False, blas_threads: int | None = 1) -> Result:
    res = Result("b")
    over = COARSE if quick else {}
    out = run_worker("rom", {"overrides": over, "n_modes": N_MODES, "n_check": 3, "n_eval": 2000, "seed": 0},
                     blas_threads=blas_threads)
    ratio = out["t_full_mean_s"] / out["t_rom_eval_s"]
    rep = out["report"]
    res.add(f"ROM build ({out['n_dofs']} DOFs, centre solve + inverse iteration at the corners, greedy)",
            f"{fmt_s(out['t_rom_build_s'])}, r = {out['rom_size']}, {len(rep['rounds'])} verification round(s), "
            f"verified: {rep['verified']}")
    res.add(f"full solve, {N_MODES} modes (mean of {len(out['checks'])})", fmt_s(out["t_full_mean_s"]))
    ratio_f = out["t_full_mean_s"] / out["t_rom_freq_s"]
    res.add("ROM evaluation, frequencies + shapes (mean of 2000 random points)", fmt_s(out["t_rom_eval_s"]))
    res.add("ratio full / ROM (frequencies + shapes: ROM.solve)", f"{ratio:,.0f}x", ">= 10,000x", ratio >= 1e4)
    res.add("ROM evaluation, frequencies only (ROM.frequencies)", fmt_s(out["t_rom_freq_s"]))
    res.add("ratio full / ROM (frequencies only)", f"{ratio_f:,.0f}x", ">= 10,000x", ratio_f >= 1e4)
    res.add("max relative frequency error (independent random points)",
            f"{out['max_error']:.1e} (min MAC {min(c['min_mac'] for c in out['checks']):.5f})", "<= 1e-4",
            out["max_error"] <= 1e-4)
    res.notes.append(("coarse test mesh (--quick); " if quick else "")
                     + f"BLAS threads per process: {blas_threads or 'default'}; the ROM tracks the lowest "
                     f"{N_MODES} modes; its greedy check errors: "
                     + ", ".join(f"{r['max_error']:.1e}" for r in rep["rounds"]))
    res.data = out
    return res
