"""Where the mesh error enters the diagnosis (jointid.diagnosis.mesh_budget): which answers take the mesh
error at their own optimum (step 8b)."""

from types import SimpleNamespace

import numpy as np

from jointid.diagnosis.mesh_budget import answer_mesh_error, softened_terms
from jointid.diagnosis.mesh_error import MeshReference


def test_a_term_softened_below_half_is_a_changed_structure_and_a_stiffened_or_added_one_is_not():
    ref = {"K_foundation": 1e15, "K_joint_n@0": 8e11, "K_feed": 1e10}
    now = {"K_foundation": 2.8e11, "K_joint_n@0": 4.1e11, "K_feed": 1.6e10, "K_new": 1.0}
    assert softened_terms(ref, now) == ["K_foundation"]
    assert softened_terms(ref, {**now, "K_joint_n@0": 3.9e11}) == ["K_foundation", "K_joint_n@0"]
    assert softened_terms(ref, ref) == []
    assert softened_terms(ref, {}) == []  # a term the solution does not name keeps its value


def _fit(k_foundation):
    return SimpleNamespace(chi2=10.0, ev=SimpleNamespace(solutions=[SimpleNamespace(kc={"K_foundation": k_foundation})]))


def test_the_answer_keeps_the_baseline_mesh_error_unless_it_softens_a_term():
    """Each case returns before any solve (``diag`` has no solver), and leaves fits and notes as they were."""
    ref = MeshReference(np.eye(2), np.zeros(2), {"kc": {"K_foundation": 1e15}, "mc": {}, "gk": {}, "gm": {}})
    diag = SimpleNamespace(data=[SimpleNamespace(mesh_reference=ref)])
    notes = []
    stiff = {"+base_support": _fit(5e14)}  # softened by 2x only
    assert answer_mesh_error(diag, stiff, "base_support", notes, print) is None
    assert answer_mesh_error(diag, stiff, None, notes, print) is None  # nothing supported
    assert answer_mesh_error(diag, {}, "base_support", notes, print) is None  # the answer not refitted
    no_budget = SimpleNamespace(data=[SimpleNamespace(mesh_reference=None)])  # no mesh error in the budget
    soft = {"+base_support": _fit(2.8e11)}
    assert answer_mesh_error(no_budget, soft, "base_support", notes, print) is None
    assert notes == [] and stiff["+base_support"].ev.solutions[0].kc["K_foundation"] == 5e14
