"""A reduced solver's subspace kept from one run to the next (``diagnosis.reuse_subspace``): the file, its
model check, and a warm run of the quick half agreeing with a cold one to the solver tolerance."""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse as sp

from jointid.fe import basis, fem, reduced, warmstart
from jointid.fe.reduced import ReducedSolver
from jointid.config.typed_diagnosis import DiagnoseJob
from conftest import truth_settings

HIDDEN = Path(__file__).parent / "hidden"


def _model(scale=1.0):
    n = 30
    K0 = sp.diags([np.full(n, 2e6), np.full(n - 1, -1e6), np.full(n - 1, -1e6)], [0, 1, -1], format="csr")
    M0 = sp.identity(n, format="csr")
    return fem.Model(stiffness={"K0": K0, "K_a": scale * sp.identity(n, format="csr")}, mass={"M0": M0},
                     fixed=np.array([0]), probe=sp.csr_matrix((1, n)), doflocs=np.zeros((3, n // 3)),
                     dof_part=np.zeros(n // 3, dtype=int))


def _solver(model, mc=None, kept=None, **kw):
    return ReducedSolver(model, {"K_a": 1e5}, mc or {}, 4, [({"K_a": 1.0}, {})], backend="scipy", basis=kept, **kw)


def test_kept_basis_is_read_back_for_its_model_only(tmp_path):
    m = _model()
    rs = _solver(m)
    path = tmp_path / "sub" / "subspace.npz"
    assert warmstart.load(path, m, 29)[0] is None  # nothing kept yet
    warmstart.save(path, rs, m)
    assert sorted(p.name for p in path.parent.iterdir()) == ["subspace.npz"]  # no temporary left behind
    kept, why = warmstart.load(path, m, 29)
    assert np.array_equal(kept.V, rs.V) and f"{rs.V.shape[1]} vectors kept" in why
    assert set(kept.Kr) == {"K0", "K_a"} and np.array_equal(kept.Kr["K_a"], rs.Kr["K_a"])
    other, why = warmstart.load(path, _model(scale=2.0), 29)
    assert other is None and "another model" in why
    path.write_bytes(b"not a zip file")
    broken, why = warmstart.load(path, m, 29)
    assert broken is None and "unreadable" in why


def test_a_basis_kept_apart_is_written_again_only_when_it_changed(tmp_path):
    m = _model()
    rs = _solver(m)
    path = tmp_path / "subspace.npz"
    warmstart.save(path, rs, m, apart=True)
    first = sorted(p.name for p in tmp_path.iterdir())
    assert len(first) == 2 and first[0] == "subspace.basis-" + first[0].split("-", 1)[1] and first[1] == "subspace.npz"
    kept, why = warmstart.load(path, m, 29)
    assert kept.source == first[0] and np.array_equal(kept.V, rs.V) and f"{rs.V.shape[1]} vectors kept" in why
    rerun = _solver(m, kept=kept)  # taken as it is, and not grown: the same file is named, not written again
    inode = (tmp_path / first[0]).stat().st_ino  # a file written again is a new file (renamed over the old)
    warmstart.save(path, rerun, m, apart=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == first and (tmp_path / first[0]).stat().st_ino == inode
    assert np.array_equal(warmstart.load(path, m, 29)[0].V, rs.V)
    rerun._append(np.random.default_rng(0).standard_normal((29, 2)))  # grown: a new file, the old one removed
    warmstart.save(path, rerun, m, apart=True)
    now = sorted(p.name for p in tmp_path.iterdir())
    assert len(now) == 2 and now[0] != first[0] and warmstart.load(path, m, 29)[0].V.shape[1] == rs.V.shape[1] + 2
    stale, fresh = tmp_path / "subspace.basis-0000000000000000.npy", tmp_path / "subspace.basis-1111111111111111.npy"
    for f in (stale, fresh):
        f.write_bytes(b"x")
    os.utime(stale, (stale.stat().st_atime - 3600, stale.stat().st_mtime - 3600))  # left by a crash an hour ago
    warmstart.save(path, _solver(m), m, apart=True)  # another run from clean: the orphan goes, a file written
    left = {p.name for p in tmp_path.iterdir()}  # a moment ago by a job beside it stays
    assert stale.name not in left and fresh.name in left
    with np.load(path) as f:
        named = str(f["basis_file"])
    (tmp_path / named).unlink()  # the basis gone: started afresh, said so
    missing, why = warmstart.load(path, m, 29)
    assert missing is None and "unreadable" in why


def test_a_kept_basis_is_taken_as_it_is_at_the_same_reference_masses(tmp_path):
    m = _model()
    rs = _solver(m)
    point = ({"K_a": 3e5}, {})
    ref = rs.solve(*point, 4)
    warmstart.save(tmp_path / "bare.npz", rs, m)
    bare = warmstart.load(tmp_path / "bare.npz", m, 29)[0]
    assert bare.KV is None and bare.MV is None  # by default formed again by the reader (results/ <= 500 MB)
    warmstart.save(tmp_path / "s.npz", rs, m, products=("KV", "MV"))
    kept = warmstart.load(tmp_path / "s.npz", m, 29)[0]
    assert kept.KV is not None and kept.KV.dtype == basis.PRODUCT_DTYPE and kept.MV is not None
    formed = [(A @ kept.V).astype(basis.PRODUCT_DTYPE) for A in (rs.K_terms["K0"], rs.M_terms["M0"])]
    same = _solver(m, kept=kept)
    assert same.n_full_solves == 0 and np.array_equal(same.V, rs.V)
    assert kept.V is None and kept.KV is None  # taken over by the solver (no second copy held while it grows)
    # the kept products are the very bits the solver would form from the kept basis
    assert np.array_equal(same.basis.KV, formed[0]) and np.array_equal(same.basis.MV, formed[1])
    assert np.array_equal(same.solve(*point, 4, refine=False).freqs_Hz, ref.freqs_Hz)
    assert same.n_factorizations == 0  # a rerun the kept basis answers never factorises (made when first asked)
    assert np.array_equal(same.fac.solve(np.ones(29)), rs.fac.solve(np.ones(29))) and same.n_factorizations == 1
    now = _solver(m, kept=warmstart.load(tmp_path / "bare.npz", m, 29)[0])  # formed when the solver starts
    assert np.array_equal(now.basis.KV, formed[0]) and np.array_equal(now.basis.MV, formed[1])
    from_bare = _solver(m, kept=bare, defer_products=True)  # deferred: the few checks of a rerun use the sparse terms
    assert from_bare.basis.deferred and from_bare.basis.KV is None and from_bare.basis.product("K", np.eye(3)) is None
    deferred = from_bare.solve(*point, 4, recheck=True)  # checked by the sparse terms
    assert deferred.error <= from_bare.tol and np.allclose(deferred.freqs_Hz, ref.freqs_Hz, rtol=1e-12)
    assert from_bare.basis.deferred  # one point checked: still deferred
    from_bare.before_check(reduced.CHECKS_BEFORE_PRODUCTS)  # many points checked: formed, the same bits
    assert not from_bare.basis.deferred
    assert np.array_equal(from_bare.basis.KV, formed[0]) and np.array_equal(from_bare.basis.MV, formed[1])
    # the estimate of the same check by the cached single-precision products: equal to far inside the tolerance
    cached = from_bare.solve(*point, 4, recheck=True)
    assert abs(cached.error - deferred.error) <= 1e-3 * from_bare.tol
    # the basis grows after the products were formed: the new columns append their own products
    from_bare._append(np.random.default_rng(3).standard_normal((29, 2)))  # (what an enrichment step does)
    grown_KV = (from_bare.K_terms["K0"] @ from_bare.V).astype(basis.PRODUCT_DTYPE)
    assert from_bare.V.shape[1] > formed[0].shape[1] and np.array_equal(from_bare.basis.KV, grown_KV)
    # factorised in a background thread while the products are formed (the diagnosis's solver): the same
    # products, the same factorisation, made once, and the same certified answers
    warmstart.save(tmp_path / "bare.npz", rs, m)
    early = ReducedSolver(m, {"K_a": 1e5}, {}, 4, [({"K_a": 1.0}, {})], backend="scipy",
                          basis=warmstart.load(tmp_path / "bare.npz", m, 29)[0], prefactor=True)
    assert np.array_equal(early.basis.KV, formed[0]) and np.array_equal(early.basis.MV, formed[1])
    assert np.array_equal(early.fac.solve(np.ones(29)), rs.fac.solve(np.ones(29))) and early.n_factorizations == 1
    assert np.array_equal(early.solve(*point, 4).freqs_Hz, ref.freqs_Hz)
    assert early.n_factorizations == 1
    # other reference masses: the basis is orthonormalised afresh, the answers stay certified
    m2 = fem.Model(stiffness=m.stiffness, mass={"M0": m.mass["M0"], "M_b": m.mass["M0"]}, fixed=m.fixed,
                   probe=m.probe, doflocs=m.doflocs, dof_part=m.dof_part)
    # a model with one term more (a hypothesis's part of another density): the kept basis serves it,
    # its solver projects the new term, and the answers are those of a solver built afresh
    kept2, why = warmstart.load(tmp_path / "s.npz", m2, 29)
    assert kept2 is not None and why.endswith("projecting the terms it was not kept with: M_b")
    assert kept2.certified == {} and kept2.sturm == {}  # made on the other model: not taken
    heavier = (point[0], {"M_b": 0.2})
    grown = _solver(m2, {"M_b": 0.2}, kept2)
    assert set(grown.Mr) == {"M0", "M_b"} and grown.n_full_solves == 0
    sol2, exact = grown.solve(*heavier, 4), _solver(m2, {"M_b": 0.2}).solve(*heavier, 4)
    assert sol2.error <= grown.tol and np.allclose(sol2.freqs_Hz, exact.freqs_Hz, rtol=1e-6)
    assert not np.allclose(sol2.freqs_Hz, ref.freqs_Hz, rtol=1e-3)  # the added mass is seen
    # a term of the kept model changed: another model
    m3 = fem.Model(stiffness={**m.stiffness, "K_a": 2.0 * m.stiffness["K_a"]}, mass=m2.mass, fixed=m.fixed,
                   probe=m.probe, doflocs=m.doflocs, dof_part=m.dof_part)
    assert "another model" in warmstart.load(tmp_path / "s.npz", m3, 29)[1]
    moved = _solver(m, {"M0": 0.1}, warmstart.load(tmp_path / "s.npz", m, 29)[0])
    sol = moved.solve(*point, 4)
    assert sol.error <= moved.tol and np.allclose(sol.freqs_Hz, ref.freqs_Hz, rtol=1e-6)


def test_points_certified_on_the_kept_columns_are_not_checked_again(tmp_path):
    m = _model()
    rs = _solver(m)
    point = ({"K_a": 3e5}, {})
    first = rs.solve(*point, 4)  # checked in the full space on this basis
    assert first.error <= rs.tol
    warmstart.save(tmp_path / "s.npz", rs, m)
    kept = warmstart.load(tmp_path / "s.npz", m, 29)[0]
    assert len(kept.certified) >= 1
    warm = _solver(m, kept=kept)
    checks = warm.n_checks
    again = warm.solve(*point, 4)
    assert warm.n_checks == checks and warm.n_checks_skipped == 1  # the kept certificate answers
    np.testing.assert_allclose(again.freqs_Hz, first.freqs_Hz, rtol=1e-12)
    assert again.error == first.error
    # a point the last run never checked is checked as always
    warm.solve({"K_a": 7e5}, {}, 4)
    assert warm.n_checks == checks + 1
    # a certificate at a point the last run checked on the kept columns takes that check (the same evidence)
    assert warm.kept_check(*point, 4) == (kept.certified_at(0)[warm._point(*point, 4)])
    warm.verify(*point, 4)
    assert warm.n_checks == checks + 1
    # a certificate at a point the last run did not check is checked in the full space
    assert warm.kept_check({"K_a": 9e5}, {}, 4) is None
    warm.verify({"K_a": 9e5}, {}, 4)
    assert warm.n_checks == checks + 2


def test_a_warm_quick_half_agrees_with_a_cold_one(tmp_path):
    """The second run starts from the first run's basis (smaller set-up, no Lanczos solve) and
    reports the same ladder to the certified tolerance; with reuse_subspace false nothing is kept."""
    from conftest import diagnosis_rig

    from jointid.synthetic import generate as synth
    from jointid.stages.diagnosis import run_current

    rig = diagnosis_rig()
    cfg = {**rig["cfg"], "effects": {"em_preload": {"beta": 0.1}}}
    synth.write_synthetic(synth.load_truth(HIDDEN / "em_preload.yaml"), truth_settings(synth.load_truth(HIDDEN / "em_preload.yaml"), rig["cfg"]), tmp_path / "ds", model=rig["model"])
    sub = tmp_path / "subspace.npz"
    runs = []
    for k in range(2):
        lines = []
        res = run_current(DiagnoseJob.from_config(cfg), tmp_path / "ds", None, tmp_path / f"out{k}", model=rig["model"], subspace=sub,
                          log=lines.append)
        runs.append((res, lines, pd.read_csv(tmp_path / f"out{k}" / "ladder.csv")))
    (cold, cold_lines, a), (warm, warm_lines, b) = runs
    assert any("no subspace kept" in ln for ln in cold_lines)
    assert any("vectors kept from the last run" in ln for ln in warm_lines)
    assert warm.solver.n_full_solves == 0 and cold.solver.n_full_solves == 1  # no Lanczos solve when warm
    # certified to 1e-6 in each eigenvalue: model frequencies within 1e-6, errors within 1e-4 percentage points
    assert list(a.variant) == list(b.variant) and list(a.state) == list(b.state)
    pct = ["max_abs_error_pct", "rms_error_pct"]
    assert np.allclose(b[pct].to_numpy(float), a[pct].to_numpy(float), rtol=0, atol=1e-4)
    assert np.allclose(b["chi2"], a["chi2"], rtol=1e-6)
    fa = pd.read_csv(tmp_path / "out0" / "current.csv")
    fb = pd.read_csv(tmp_path / "out1" / "current.csv")
    assert np.allclose(fb["freq_model_Hz"], fa["freq_model_Hz"], rtol=1e-6, atol=0, equal_nan=True)
    off = {**cfg, "diagnosis": {**(cfg.get("diagnosis") or {}), "reuse_subspace": False}}
    sub2 = tmp_path / "off.npz"
    lines = []
    run_current(DiagnoseJob.from_config(off), tmp_path / "ds", None, tmp_path / "out2", model=rig["model"], subspace=sub2, log=lines.append)
    assert not sub2.exists() and not any("kept" in ln for ln in lines)
