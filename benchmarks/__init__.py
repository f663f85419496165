"""Benchmarks of jointid (issue 7): ``python -m benchmarks [a b c d e f g h i j] [--quick]``.

=====  =======================================================================================
``a``  default-model assembly + 12-mode modal solve: jointid vs idiomatic scikit-fem, the ratio
``b``  reduced-order model evaluation vs full solve: speed ratio and max frequency error
``c``  full ``snakemake -j2`` from a clean results directory (tmp copy): wall time, peak memory
``d``  scaling of a full solve with DOFs (20k, 75k, 150k, 300k): time, peak RSS, fitted exponent
``e``  mesh convergence: first 12 frequencies of the default model vs a once-refined mesh
``f``  identified joint parameters re-identified on a refined mesh: their change
``g``  where the lateral modes lose mesh convergence: grid lines added beside one set of part edges
``h``  the loop: enable one effect in the config and rerun the diagnosis target (tmp copy): wall time
``i``  the eigen-solve alone on one factor: block shift-invert Lanczos vs ARPACK, time and agreement
``j``  coverage study of the diagnosis on synthetic cases: named effect, false claims, 95 % intervals
=====  =======================================================================================

Every measurement that matters for memory runs in its own subprocess (``benchmarks.worker``), which
reports its own peak RSS (``resource.getrusage``).  Results go to ``benchmarks/out/`` (git-ignored):
one JSON per benchmark and ``summary.md`` with the table that is printed.
"""

BENCHMARKS = ("a", "b", "c", "d", "e", "f", "g", "h", "i", "j")
