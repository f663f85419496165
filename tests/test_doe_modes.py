"""The DOE points' modes on one reduced basis (``solver.method: reduced``) against a full FE solve at
each point (``solver.method: full``, the reference path; issue 39: equivalence on the same mesh).

The coarse rig and its face-centred design over the whole parameter box (the DOE spans a decade
or more per parameter): every frequency within 1e-6 relative, every shape's MAC with the full
solve's at least 0.9999, the same mode descriptions.  A forced failure of the residual check makes
the full solve answer, and the log says so.
"""

import numpy as np
import pytest

from conftest import coarse_config_dict
from jointid.config import load_config
from jointid.config.typed import ModelSpec
from jointid.correlate.mac import mac
from jointid.fe import certify
from jointid.fe.model import build_model
from jointid.identification.doe_modes import centre, solve_points
from jointid.identification.polish import solve_point
from jointid.config.options import DoeOptions
from jointid.stages.doe import doe_sheet


@pytest.fixture(scope="module")
def case():
    cfg = load_config(coarse_config_dict())
    spec = ModelSpec.from_config(cfg)
    model = build_model(spec)
    sheet = doe_sheet(DoeOptions.from_config(cfg))
    names = spec.joints.names
    thetas = [{n: float(v) for n, v in zip(names, row)} for row in sheet[names].to_numpy(float)]
    full = [solve_point(spec, model, th) for th in thetas]
    return spec, model, thetas, full


def _compare(reduced, full):
    worst_f, worst_mac = 0.0, 1.0
    for r, (f, shapes, desc, _) in zip(reduced, full):
        worst_f = max(worst_f, float(np.max(np.abs(r.freqs_Hz / f - 1))))
        worst_mac = min(worst_mac, float(np.min(np.diag(mac(r.shapes, shapes)))))
        assert list(r.description["description"]) == list(desc["description"])
    return worst_f, worst_mac


def test_centre_is_the_geometric_mean():
    got = centre([{"k": 1e10, "c": 4.0}, {"k": 1e12, "c": 1.0}])
    assert got["k"] == pytest.approx(1e11, rel=1e-12) and got["c"] == pytest.approx(2.0, rel=1e-12)


def test_every_doe_point_on_one_reduced_basis_equals_its_full_solve(case):
    spec, model, thetas, full = case
    lower, upper = np.array(spec.joints.lower_N_per_m3), np.array(spec.joints.upper_N_per_m3)
    assert np.all(upper / lower >= 10)  # the design spans the box: far from the basis's centre
    reduced = list(solve_points(spec, model, thetas))
    worst_f, worst_mac = _compare(reduced, full)
    print(f"{len(thetas)} DOE points: frequencies {worst_f:.1e} (relative), smallest MAC {worst_mac:.8f}, "
          f"basis {reduced[-1].basis_size} vectors")
    assert worst_f <= 1e-6
    assert worst_mac >= 0.9999
    assert all(r.error <= 1e-6 for r in reduced)
    assert reduced[-1].basis_size > reduced[0].basis_size  # it grew where points needed it


def test_a_point_whose_check_fails_is_answered_by_the_full_solve(case, monkeypatch):
    spec, model, thetas, full = case
    monkeypatch.setattr(certify, "MAX_ROUNDS", 1)  # one enrichment round cannot reach the far corners
    lines = []
    reduced = list(solve_points(spec, model, thetas[:3], log=lines.append))
    fallbacks = [m for m in lines if "residual check failed after 1 enrichment rounds" in m]
    assert fallbacks, lines
    worst_f, worst_mac = _compare(reduced, full[:3])
    assert worst_f <= 1e-6 and worst_mac >= 0.9999
