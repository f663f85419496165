"""``python -m benchmarks [a b c d e f g h i j] [--quick] [--blas-threads N]``: run, print one table, save.

Benchmark ``j`` (the coverage study, docs/validation.md) takes ``--cases N``, ``--rig coarse|default`` and
``--set KEY=VALUE`` (diagnosis options); its page is docs/validation.md, not docs/performance.md.

Without names every benchmark runs.  ``--quick`` uses the coarse test mesh and small sizes (a few
minutes in all); the full run builds models up to ~360k DOFs and runs the whole workflow once.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time

from . import BENCHMARKS
from .common import OUT, format_table, load_result, write_result
from .performance import write_performance

MODULES = {"a": "bench_a_solve", "b": "bench_b_rom", "c": "bench_c_workflow", "d": "bench_d_scaling",
           "e": "bench_e_convergence", "f": "bench_f_param_mesh",
           "g": "bench_g_edges", "h": "bench_h_loop", "i": "bench_i_eigen",
           "j": "bench_j_coverage"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("names", nargs="*", choices=[[], *BENCHMARKS], metavar="NAME",
                    help="benchmarks to run: " + ", ".join(BENCHMARKS) + " (default: all)")
    ap.add_argument("--quick", action="store_true", help="coarse mesh and small sizes (smoke test)")
    ap.add_argument("--report", action="store_true",
                    help="print the table from the saved results in benchmarks/out (run nothing)")
    ap.add_argument("--compare", metavar="COMMIT",
                    help="(c) also run the workflow of COMMIT (its own code), then this one again, and give the "
                         "ratio old / new (new: the mean of the runs before and after the old)")
    ap.add_argument("--blas-threads", type=int, default=1,
                    help="OPENBLAS/OMP threads per worker process (0 = library default; default 1)")
    from .bench_j_coverage import add_arguments

    add_arguments(ap)
    a = ap.parse_args(argv)
    names = [n for n in BENCHMARKS if n in (a.names or BENCHMARKS)]
    if a.report:
        results = [r for r in (load_result(n, a.quick) for n in names) if r is not None]
        print(format_table(results))
        return 0 if results else 1
    results = []
    for name in names:
        t0 = time.perf_counter()
        print(f"[benchmarks] running ({name}) ...", file=sys.stderr, flush=True)
        mod = importlib.import_module(f".{MODULES[name]}", __package__)
        kw = {"compare": a.compare} if name == "c" and a.compare else {}
        if name == "j":
            kw = {"cases": a.cases, "rig": a.rig, "options": mod.parse_options(a.set), "subset": a.subset,
                  "only": tuple(x for x in a.only.split(",") if x), "shard": mod.parse_shard(a.shard),
                  "resume": a.resume,
                  "command": "python -m benchmarks " + " ".join(argv if argv is not None else sys.argv[1:])}
        res = mod.run(quick=a.quick, blas_threads=a.blas_threads or None, **kw)
        res.data["benchmark_wall_s"] = time.perf_counter() - t0
        write_result(res, a.quick)
        results.append(res)
        print(f"[benchmarks] ({name}) done in {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    table = format_table(results)
    header = (f"jointid benchmarks{' (--quick)' if a.quick else ''}, {time.strftime('%Y-%m-%d %H:%M')}, "
              f"BLAS threads per process: {a.blas_threads or 'default'}\n\n")
    print(header + table)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"summary{'_quick' if a.quick else ''}{'_' + ''.join(names) if a.names else ''}.md").write_text(
        header + table + "\n")
    if not a.quick:
        write_performance([r for r in results if r.name != "j"])  # j's page: docs/validation.md
    return 0


if __name__ == "__main__":
    sys.exit(main())
