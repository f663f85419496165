"""Thread limits of the dense and sparse linear-algebra libraries (through ``threadpoolctl``).

The diagnosis and the synthetic-data writer do many small dense products; on a shared 2-core
machine a multithreaded BLAS oversubscribes the cores and runs about ten times slower.
"""

from __future__ import annotations


def limit_threads(n: int = 1) -> list[str]:
    """Limit every loaded BLAS thread pool (OpenBLAS, MKL with PARDISO) to ``n`` threads.

    MKL is loaded first (``pypardiso``, when installed) so that its pool is limited too; the limit
    holds for the rest of the process.  Returns the libraries adjusted, as ``"<path>:<api>"``.
    """
    from threadpoolctl import threadpool_limits, threadpool_info

    try:  # load MKL (PARDISO) now, so that its thread count is set too
        import pypardiso  # noqa: F401
    except Exception:
        pass
    threadpool_limits(limits=int(n), user_api="blas")
    return [f"{lib['filepath']}:{lib['internal_api']}" for lib in threadpool_info()
            if lib["internal_api"] in ("openblas", "mkl", "blis")]
