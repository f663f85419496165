"""The certificate record of a reported optimum (jointid.fe.certificate): the reduced solver's
residual check, a full solve's residual and Sturm count, the fallback to the full solve when a check
fails, and the record's way through JSON."""

import json
import warnings

import numpy as np
import pytest

from jointid import io
from jointid.errors import NumericalWarning
from jointid.fe import certify
from jointid.fe.certificate import Certificate, full_certificate, reduced_certificate
from jointid.fe.modal import solve_model
from jointid.fe.reduced import ReducedSolver
from jointid.identification.record import FePolish, IdentificationRecord, Interval, PolishedOn
from jointid.stages.verify import write_certificate

from test_certify import FAR, N_MODES, NEAR, REF, _chain
from test_sturm import _Pencil, twin_chains

RECORD_KEYS = {"method", "n_modes", "max_relative_residual", "residual_measure", "residual_tol", "sturm_shift_Hz",
               "sturm_count", "n_modes_below_shift", "complete", "passed", "fallback"}


@pytest.fixture()
def model():
    return _chain()


def _solver(model, lines=None):
    rs = ReducedSolver(model, *REF, N_MODES, [({"K_ground": 1.0}, {}), ({}, {"M_point": 1.0})], backend="scipy")
    rs.log = None if lines is None else lines.append
    return rs


def _through_json(cert: Certificate, tmp_path) -> dict:
    """The record written as the stages write JSON and read back; read again into a certificate, it
    gives the same record (the residual rounded to three digits, every other field as it was)."""
    path = tmp_path / "certificate.json"
    io.write_json(path, cert.to_record())
    rec = json.loads(path.read_text())
    back = Certificate.from_record(rec)
    assert back.to_record() == rec
    for k, v in vars(cert).items():
        got = getattr(back, k)
        if isinstance(v, float) and not np.isfinite(v):
            assert got is None, k
        elif isinstance(v, float):  # JSON keeps 12 digits (jointid.io), the residual 3
            assert got == pytest.approx(v, rel=5e-3 if k == "max_relative_residual" else 1e-11), k
        else:
            assert got == v, k
    return rec


def test_record_round_trips_through_json(tmp_path):
    cert = Certificate("full", 6, 3.2e-12, "relative residual", 1e-6, sturm_shift_Hz=412.5, sturm_count=6,
                       n_modes_below_shift=6, fallback="Sturm count 6 below 412.5 Hz, 5 found")
    rec = _through_json(cert, tmp_path)
    assert set(rec) == RECORD_KEYS
    assert rec["complete"] is True and rec["passed"] is True
    assert Certificate.from_record(rec) == cert
    assert Certificate.from_record(json.loads(json.dumps(cert.to_record()))).to_record() == cert.to_record()
    # not counted, not checked: null in JSON, and no pass
    bare = Certificate("reduced", 6, float("nan"), "estimated error", 1e-6)
    rec = _through_json(bare, tmp_path)
    assert rec["max_relative_residual"] is None and rec["complete"] is None and rec["passed"] is False
    # a count that disagrees fails the certificate whatever the residual
    short = Certificate("full", 6, 1e-12, "relative residual", 1e-6, 400.0, 7, 6)
    assert short.complete is False and not short.passed and "FAILED" in short.describe()


def test_a_converged_reduced_solve_is_certified_without_fallback(model, tmp_path):
    rs = _solver(model)
    sol = rs.solve(*NEAR, N_MODES)
    full_before = rs.n_full_solves
    cert = reduced_certificate(rs, *NEAR, N_MODES)
    assert rs.n_full_solves == full_before  # the record only reads the check
    assert cert.method == "reduced" and cert.fallback is None and cert.passed
    assert cert.max_relative_residual == sol.error <= rs.tol
    assert cert.complete is None  # the reduced solver's record carries no Sturm count
    assert _through_json(cert, tmp_path)["method"] == "reduced"


def test_a_failed_residual_check_falls_back_to_the_full_solve(model, monkeypatch, tmp_path):
    """One enrichment round is not enough at a point far from the reference: the check fails and
    the full solve answers, logged, recorded in the certificate, and equal to a direct full solve."""
    monkeypatch.setattr(certify, "MAX_ROUNDS", 1)
    lines = []
    rs = _solver(model, lines)
    full_before = rs.n_full_solves
    sol = rs.solve(*FAR, N_MODES)
    assert rs.n_full_solves == full_before + 1, "the fallback's full solve ran"
    direct = solve_model(model, *FAR, N_MODES, backend="scipy")
    np.testing.assert_allclose(sol.freqs_Hz, direct.freqs_Hz, rtol=1e-6)
    assert any("certificate failed (residual check failed after 1 enrichment rounds" in m for m in lines)
    cert = reduced_certificate(rs, *FAR, N_MODES)
    assert cert.method == "full" and cert.fallback.startswith("residual check failed after 1 enrichment rounds")
    assert cert.passed  # the full solve's modes pass the check
    rec = _through_json(cert, tmp_path)
    assert rec["method"] == "full" and "residual check failed" in rec["fallback"]
    # the point is now certified: a second solve neither refines nor solves again
    again = rs.solve(*FAR, N_MODES)
    assert rs.n_full_solves == full_before + 1 and np.array_equal(again.freqs_Hz, sol.freqs_Hz)


def test_without_a_failed_check_the_same_point_stays_reduced(model):
    """The reference for the test above: with the usual rounds the far point converges by enrichment."""
    rs = _solver(model)
    sol = rs.solve(*FAR, N_MODES)
    cert = reduced_certificate(rs, *FAR, N_MODES)
    assert cert.method == "reduced" and cert.fallback is None and cert.passed
    np.testing.assert_allclose(sol.freqs_Hz, solve_model(model, *FAR, N_MODES, backend="scipy").freqs_Hz, rtol=1e-6)


def test_a_failed_sturm_count_falls_back_to_a_second_solve_and_says_so(tmp_path):
    K, M, f = twin_chains(80)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        modes = solve_model(_Pencil(K, M), {}, {}, 6, backend="scipy", certify=True)
    np.testing.assert_allclose(modes.freqs_Hz, f[:6], rtol=1e-9)
    cert = full_certificate(modes)
    assert cert.method == "full" and cert.complete and cert.passed
    assert cert.sturm_count == cert.n_modes_below_shift == int(np.sum(f < cert.sturm_shift_Hz))
    assert "missed mode(s) recovered by a second solve" in cert.fallback
    assert cert.max_relative_residual <= 1e-6
    assert "recovered" in _through_json(cert, tmp_path)["fallback"]


def test_verify_writes_the_certificate_beside_the_identifications(model, tmp_path):
    modes = solve_model(model, *NEAR, N_MODES, backend="scipy", certify=True)
    polish = reduced_certificate(_solver_at_near(model), *NEAR, N_MODES).to_record()
    par = IdentificationRecord({"k_normal_N_per_m3": Interval(1e12)},
                               fe_polish=FePolish(PolishedOn.FE, (), (), 0.0, 1, 1.0, 0, (), (), (), polish))
    paths = [tmp_path / "a.json", tmp_path / "b.json"]
    for p in paths:
        write_certificate("power_off", par, modes, str(p))
    assert paths[0].read_bytes() == paths[1].read_bytes()  # no time or host in the record
    doc = json.loads(paths[0].read_text())
    assert doc["state"] == "power_off" and doc["parameters"] == {"k_normal_N_per_m3": 1e12}
    assert doc["identify"] == json.loads(json.dumps(io._jsonable(polish))) and doc["identify"]["method"] == "reduced"
    ver = doc["verify"]
    assert set(ver) == RECORD_KEYS and ver["method"] == "full" and ver["fallback"] is None
    assert ver["passed"] and ver["complete"] and ver["sturm_count"] == ver["n_modes_below_shift"] >= N_MODES - 1


def _solver_at_near(model):
    rs = _solver(model)
    rs.solve(*NEAR, N_MODES)
    return rs
