"""jointid.fe.affine.sequential_sum: the sum of a base matrix and a few sparse terms, to the bit of adding whole
matrices one by one (the mesh error's refined stiffness, jointid.diagnosis.terms.System.K)."""

import numpy as np
import scipy.sparse as sp

from jointid.fe.affine import sequential_sum


def _one_by_one(base, parts):
    out = base.copy()
    for c, A in parts:
        out = out + c * A
    return out.tocsr()


def _same_bits(a, b) -> bool:
    return (np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
            and np.array_equal(a.data, b.data) and a.shape == b.shape)


def test_a_few_terms_on_few_rows_sum_to_the_bits_of_whole_matrices_added_one_by_one():
    rng = np.random.default_rng(7)
    n = 400
    base = sp.random(n, n, density=0.05, random_state=1, format="csr")
    base = (base + base.T).tocsr()
    base.data[::17] = 0.0  # explicit zeros: the first sum drops them, in every row
    parts = []
    for k in range(6):  # terms on a few rows each, overlapping one another and the base
        rows = rng.choice(n, 8, replace=False)
        A = sp.coo_matrix((rng.normal(size=40), (rng.choice(rows, 40), rng.integers(0, n, 40))), shape=(n, n))
        parts.append((float(rng.uniform(1e3, 1e9)), A.tocsr()))
    # an entry the terms cancel to exactly zero is dropped, as the one-by-one sum drops it
    i, j = parts[0][1].nonzero()
    cancel = sp.csr_matrix(([-parts[0][0] * parts[0][1][i[0], j[0]] - base[i[0], j[0]]], ([i[0]], [j[0]])), shape=(n, n))
    parts.append((1.0, cancel))
    want, got = _one_by_one(base, parts), sequential_sum(base, parts)
    assert _same_bits(want, got)
    assert got[i[0], j[0]] == 0.0 and want.nnz == got.nnz
    assert _same_bits(sequential_sum(base, parts[::-1]), _one_by_one(base, parts[::-1]))  # the order is kept
    assert _same_bits(sequential_sum(base, []), base) and sequential_sum(base, []) is not base
