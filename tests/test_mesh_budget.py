"""Where the mesh error enters the diagnosis (jointid.diagnosis.mesh_budget): which refits move the point
the mesh error is computed at."""

from types import SimpleNamespace

import numpy as np

from jointid.diagnosis.mesh_budget import REPOINT_CHI2, repoint, softened_terms
from jointid.diagnosis.mesh_error import MeshReference


def test_a_term_softened_below_half_is_a_changed_structure_and_a_stiffened_or_added_one_is_not():
    ref = {"K_foundation": 1e15, "K_joint_n@0": 8e11, "K_feed": 1e10}
    now = {"K_foundation": 2.8e11, "K_joint_n@0": 4.1e11, "K_feed": 1.6e10, "K_new": 1.0}
    assert softened_terms(ref, now) == ["K_foundation"]
    assert softened_terms(ref, {**now, "K_joint_n@0": 3.9e11}) == ["K_foundation", "K_joint_n@0"]
    assert softened_terms(ref, ref) == []


def test_repoint_leaves_the_mesh_error_where_it_is_unless_the_answer_softens_a_term_and_fits_better():
    """No diagnoser work is done (``diag`` has no solver): each case returns None before any solve."""
    ref = MeshReference(np.eye(2), np.zeros(2), {"kc": {"K_foundation": 1e15}, "mc": {}, "gk": {}, "gm": {}})
    diag = SimpleNamespace(data=[SimpleNamespace(mesh_reference=ref)])
    current = SimpleNamespace(chi2=1000.0)

    def fit(chi2, k):
        return SimpleNamespace(chi2=chi2, ev=SimpleNamespace(solutions=[SimpleNamespace(kc={"K_foundation": k})]))

    notes = []
    stiff = {"+base_support": fit(10.0, 5e14)}  # softened by 2x only
    assert repoint(diag, current, stiff, "base_support", notes, print) is None
    close = {"+base_support": fit(1000.0 - REPOINT_CHI2 / 2, 2.8e11)}  # not better by enough
    assert repoint(diag, current, close, "base_support", notes, print) is None
    assert repoint(diag, current, {}, "base_support", notes, print) is None  # the answer not refitted
    plain = SimpleNamespace(data=[SimpleNamespace(mesh_reference=None)])  # no mesh error in the budget
    assert repoint(plain, current, {"+base_support": fit(10.0, 2.8e11)}, "base_support", notes, print) is None
    assert notes == []
