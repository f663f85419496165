"""Thread limits of the dense and sparse linear-algebra libraries (through ``threadpoolctl``).

The diagnosis and the synthetic-data writer do many small dense products; on a shared 2-core
machine a multithreaded BLAS oversubscribes the cores and runs about ten times slower.
"""

from __future__ import annotations

import functools
import glob
import os
import sys


def limit_threads(n: int = 1) -> list[str]:
    """Limit every loaded BLAS thread pool (OpenBLAS, MKL with PARDISO) to ``n`` threads.

    MKL is loaded first (``pypardiso``, when installed) so that its pool is limited too; the limit
    holds for the rest of the process.  Returns the libraries adjusted, as ``"<path>:<api>"``.
    """
    from threadpoolctl import threadpool_limits, threadpool_info

    try:  # load MKL (PARDISO) now, so that its thread count is set too
        import_pypardiso()
    except Exception:
        pass
    threadpool_limits(limits=int(n), user_api="blas")
    return [f"{lib['filepath']}:{lib['internal_api']}" for lib in threadpool_info()
            if lib["internal_api"] in ("openblas", "mkl", "blis")]


def import_pypardiso():
    """``import pypardiso``, pointed at MKL's runtime library first (``PYPARDISO_MKL_RT``).

    Without the variable, every ``PyPardisoSolver()`` (one at import, one per factorisation) searches
    the whole environment tree for the library, a recursive glob of about 0.3 s: a modal job on the
    coarse test mesh spent a third of its time there.  A user's own setting is kept; when the library
    is not in ``<prefix>/lib``, pypardiso searches as before.
    """
    _locate_mkl_runtime()
    import pypardiso

    return pypardiso


@functools.cache
def _locate_mkl_runtime() -> None:
    if os.environ.get("PYPARDISO_MKL_RT"):
        return
    for lib in sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len):
        os.environ["PYPARDISO_MKL_RT"] = lib
        return
