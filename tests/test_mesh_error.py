"""The diagnosis's mesh error (jointid.diagnosis.mesh_error): the axis halvings, one at a time, add up
to a uniform refinement of the mesh, which is what the correction stands for."""

import numpy as np
import pytest

from conftest import diagnosis_rig


@pytest.fixture(scope="module")
def halvings():
    """The coarse rig's modes at the probe on its own mesh, on each one-axis halving and on the uniform
    refinement (``refine: 2``, 110k DOFs), the refined modes followed by MAC: ``(f0, p0, {mesh: (f, p)})``."""
    from jointid.config.typed import ModelSpec
    from jointid.correlate.pairing import pair_by_shapes
    from jointid.diagnosis.mesh_error import DEFAULT_HALVE
    from jointid.diagnosis.terms import baseline_coefficients, build_system
    from jointid.fe.modal import solve_modes
    from jointid.fe.model import build_model

    rig = diagnosis_rig()
    cfg, spec = rig["cfg"], ModelSpec.from_config(rig["cfg"])
    theta = {"k_normal_N_per_m3": 7e11, "k_lateral_N_per_m3": 6e11}

    def solve(model):
        s = build_system(model, ModelSpec.from_config(cfg))
        kc, mc = baseline_coefficients(s, spec, theta)
        m = solve_modes(s.K(kc), s.M(mc), 6, fixed=s.fixed)
        return m.freqs_Hz, s.probe @ m.phi

    f0, p0 = solve(rig["model"])
    out = {}
    for name, model in [(cls, build_model(spec, halve=(cls,))) for cls in DEFAULT_HALVE] + \
            [("uniform", build_model(spec, refine=2))]:
        f, p = solve(model)
        follow, _ = pair_by_shapes(p0, p, threshold=0.8)
        assert (follow >= 0).all()
        out[name] = (f[follow], p[:, follow])
    return f0, p0, out


def test_axis_halvings_add_up_to_a_uniform_refinement(halvings):
    """Known truth: the coarse rig solved with every cell halved along all three axes (``refine: 2``,
    110k DOFs).  The summed log shifts of the three one-axis halvings (about 33k DOFs each) must match
    its shifts to 10 % on every mode that moves by more than 0.3 %; the thickness alone (the mesh
    check's default) must not (it finds less than half).  Measured when written: within 4 %."""
    f0, _, solved = halvings
    one = {k: np.log(f / f0) for k, (f, _) in solved.items() if k != "uniform"}
    uniform = np.log(solved["uniform"][0] / f0)
    total = sum(one.values())
    moved = np.abs(uniform) > 0.003
    assert moved.sum() >= 3
    assert np.all(np.abs(total - uniform)[moved] <= 0.10 * np.abs(uniform)[moved]), (total, uniform)
    assert np.all(np.abs(one["thickness"])[moved] < 0.6 * np.abs(uniform)[moved])
    assert np.all(total <= 0)  # a nested refinement only lowers the frequencies


def test_axis_halvings_shape_changes_add_up_to_a_uniform_refinements(halvings):
    """Known truth as above, for the probe shapes: the refined shape scaled to the run mesh's by least
    squares, less the run mesh's (``mesh_error._class_shift``'s change).  On every mode whose shape moves
    by more than 0.5 % of its norm on the uniform refinement (0.6 - 1.5 % here), the summed changes of the
    three halvings leave at most a fifth of the uniform refinement's change uncorrected and point the same
    way (cosine above 0.95).  Measured when written: at most 9 % left, cosines 0.997 - 0.999."""
    _, p0, solved = halvings

    def change(p):
        return p * (np.sum(p0 * p, axis=0) / np.sum(p * p, axis=0)) - p0

    total = sum(change(p) for k, (_, p) in solved.items() if k != "uniform")
    uniform = change(solved["uniform"][1])
    size = np.linalg.norm(uniform, axis=0) / np.linalg.norm(p0, axis=0)
    moved = size > 0.005
    assert moved.sum() >= 2, size
    left = np.linalg.norm(uniform - total, axis=0)
    assert np.all(left[moved] <= 0.2 * np.linalg.norm(uniform, axis=0)[moved]), (left, size)
    cos = np.sum(uniform * total, axis=0) / (np.linalg.norm(uniform, axis=0) * np.linalg.norm(total, axis=0))
    assert np.all(cos[moved] > 0.95), cos


def test_the_shape_correction_keeps_each_modes_scale_and_sign_and_its_known_error_is_its_size():
    """Analytic: reference modes a, b with shape changes da, db.  A mode solved again as -2 a takes -2 da
    (its own scale and sign); the known error of its entries, relative to its RMS, is |da| / rms(a) there;
    a mode no refined mesh followed adds its floor in quadrature."""
    from types import SimpleNamespace

    from jointid.diagnosis.mesh_error import MeshReference, shape_change, shape_known

    a, b = np.array([1.0, 0.0, 0.0, 1.0]), np.array([0.0, 1.0, 1.0, 0.0])
    da, db = np.array([0.0, 0.02, -0.02, 0.0]), np.array([0.01, 0.0, 0.0, -0.01])
    ref = MeshReference(np.column_stack([a, b]), np.zeros(2), None, np.column_stack([da, db]), np.array([0.0, 0.03]))
    shapes = np.column_stack([b, -2 * a])
    assert np.allclose(shape_change(ref, shapes), np.column_stack([db, -2 * da]))
    d = SimpleNamespace(mesh_reference=ref)
    rows = np.array([True, True, True, False])
    k_a = shape_known(d, shapes, rows, 1)
    rms = np.sqrt(np.mean((2 * a[rows]) ** 2))
    assert np.allclose(k_a, np.abs(2 * da[rows]) / rms)
    k_b = shape_known(d, shapes, rows, 0)
    assert np.allclose(k_b, np.sqrt((db[rows] / np.sqrt(np.mean(b[rows] ** 2))) ** 2 + 0.03 ** 2))
    assert shape_known(SimpleNamespace(mesh_reference=None), shapes, rows, 0) is None


def test_the_correction_follows_each_model_mode_and_blends_mixed_ones():
    """Analytic: two reference modes with corrections -1 % and -3 %.  Solved again with their order
    swapped, each keeps its own correction; a mode that is an equal mix of the two takes the mean
    (MAC² weights 0.5 / 0.5); a state without a reference is left as it was."""
    from types import SimpleNamespace

    from jointid.diagnosis.mesh_error import MeshReference, correct
    from jointid.fe.reduced import Solution

    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    ref = np.column_stack([a, b])
    shift = np.log([0.99, 0.97])
    d = SimpleNamespace(mesh_reference=MeshReference(ref, shift))

    def sol(shapes, f):
        n = len(f)
        return Solution(np.asarray(f, float), np.ones(n), np.zeros((1, n)), np.ones(n), np.zeros((1, n)), {}, {},
                        np.column_stack(shapes))

    swapped = correct(d, sol([b, a], [1000.0, 1010.0]))
    assert np.allclose(swapped.freqs_Hz, [970.0, 999.9])
    mixed = correct(d, sol([(a + b) / np.sqrt(2)], [1000.0]))
    assert np.allclose(mixed.freqs_Hz, [1000.0 * np.exp(shift.mean())])
    plain = sol([a], [1000.0])
    assert correct(SimpleNamespace(mesh_reference=None), plain) is plain


def test_a_mode_the_reference_does_not_have_takes_its_solids_share_of_the_correction():
    """Analytic: two reference modes (-1 %, -3 %) and a correction per unit solids' energy share of -2 %.
    A mode orthogonal to both at the probe (an elastic base's own mode on a clamped reference) takes
    -2 % times its solids' share (0.1: -0.2 %); a mode the references hold (MAC 1) keeps its own
    correction whatever its share; one in between (MAC² sum 0.32, half of the 0.64 that counts as held)
    takes the mean of the two; without a share the old blend stands."""
    from types import SimpleNamespace

    from jointid.diagnosis.mesh_error import FOLLOW_MAC, MeshReference, correct
    from jointid.fe.reduced import Solution

    a, b, c = np.eye(3)
    shift = np.log([0.99, 0.97])
    d = SimpleNamespace(mesh_reference=MeshReference(np.column_stack([a, b]), shift, per_solid=-0.02))

    def sol(shapes, f):
        n = len(f)
        return Solution(np.asarray(f, float), np.ones(n), np.zeros((1, n)), np.ones(n), np.zeros((1, n)), {}, {},
                        np.column_stack(shapes))

    out = correct(d, sol([c, a], [2700.0, 1000.0]), np.array([0.1, 0.3]))
    np.testing.assert_allclose(out.freqs_Hz, [2700.0 * np.exp(-0.002), 990.0])
    half = (0.5 * FOLLOW_MAC ** 2) ** 0.25  # MAC² with a: 0.32, held half
    mode = half * a + np.sqrt(1 - half ** 2) * c
    out = correct(d, sol([mode], [2000.0]), np.array([0.5]))
    np.testing.assert_allclose(out.freqs_Hz, [2000.0 * np.exp(0.5 * np.log(0.99) + 0.5 * -0.02 * 0.5)])
    assert correct(d, sol([a], [1000.0])).freqs_Hz[0] == 990.0


def test_the_mesh_errors_change_with_the_joints_is_its_energy_share_change():
    """Known truth: the correction of one halving class (thickness) computed at two joint stiffnesses,
    1.35x apart (as em_preload makes between two states).  Its first-order change predicted at the
    first point from the energy shares (``mesh_error._shares``, the gradient of :func:`drift`) must
    match the change actually found, to 35 % of it on every mode whose correction moves by more than
    0.02 % (and in sign): the part of the mesh error that differs between two states is known, not
    zero and not the whole correction."""
    from types import SimpleNamespace

    from jointid.config.typed import ModelSpec
    from jointid.diagnosis import mesh_error as me
    from jointid.diagnosis.terms import baseline_coefficients, build_system
    from jointid.fe.modal import solve_modes
    from jointid.fe.model import build_model

    rig = diagnosis_rig()
    cfg, spec = rig["cfg"], ModelSpec.from_config(rig["cfg"])
    coarse = build_system(rig["model"], ModelSpec.from_config(cfg))
    fine = build_system(build_model(spec, halve=("thickness",)), ModelSpec.from_config(cfg))

    def state(theta):
        kc, mc = baseline_coefficients(coarse, spec, theta)
        m = solve_modes(coarse.K(kc), coarse.M(mc), 8, fixed=coarse.fixed)
        lam = (2 * np.pi * m.freqs_Hz) ** 2
        return SimpleNamespace(kc=kc, mc=mc, freqs_Hz=m.freqs_Hz, shapes=coarse.probe @ m.phi, phi=m.phi, lam=lam)

    a = state({"k_normal_N_per_m3": 7e11, "k_lateral_N_per_m3": 6e11})
    b = state({"k_normal_N_per_m3": 7e11 * 1.35, "k_lateral_N_per_m3": 6e11 * 1.35})
    shift_a, (fk, fm) = me._class_shift(fine, a, 8, shares=True)[:2]
    shift_b = me._class_shift(fine, b, 8).shift
    ck, cm = me._shares(coarse, a.phi, a.lam, a)
    predicted = np.zeros(len(shift_a))
    for fine_g, coarse_g, now, ref in ((fk, ck, b.kc, a.kc), (fm, cm, b.mc, a.mc)):
        for t in coarse_g:
            predicted += 0.5 * np.nan_to_num(fine_g[t] - coarse_g[t]) * (now.get(t, 0.0) - ref.get(t, 0.0))
    from jointid.correlate.pairing import pair_by_shapes

    follow, _ = pair_by_shapes(a.shapes, b.shapes, threshold=0.8)
    ok = follow >= 0
    actual = shift_b[follow[ok]] - shift_a[ok]
    pred = predicted[ok]
    moved = np.abs(actual) > 2e-4
    assert moved.sum() >= 2, actual
    assert np.all(np.sign(pred[moved]) == np.sign(actual[moved])), (pred, actual)
    assert np.all(np.abs(pred - actual)[moved] <= 0.35 * np.abs(actual)[moved]), (pred, actual)


def test_the_refined_meshes_give_the_same_numbers_in_a_process_of_their_own_and_in_this_one():
    """refined_shifts through jointid.isolate (the default mesh's way: a child process, for memory) and in the
    caller's process (a mesh below ISOLATE_DOFS, the coarse rig's): the same shifts, shares and shape changes, to
    the bit."""
    from jointid import isolate
    from jointid.config.typed import ModelSpec
    from jointid.diagnosis.mesh_error import ISOLATE_DOFS, Point, refined_shifts
    from jointid.diagnosis.terms import baseline_coefficients, build_system
    from jointid.fe.modal import solve_modes

    rig = diagnosis_rig()
    spec = ModelSpec.from_config(rig["cfg"])
    s = build_system(rig["model"], spec)
    assert s.n_dofs < ISOLATE_DOFS  # the coarse rig is refined in the diagnosis's own process
    kc, mc = baseline_coefficients(s, spec, {"k_normal_N_per_m3": 7e11, "k_lateral_N_per_m3": 6e11})
    m = solve_modes(s.K(kc), s.M(mc), 6, fixed=s.fixed)
    points = [Point(kc, mc, m.freqs_Hz, s.probe @ m.phi)]
    here = refined_shifts(spec, ("thickness",), points, 6, True)
    there = isolate.call(refined_shifts, spec, ("thickness",), points, 6, True)
    assert here[1] == there[1]
    (a,), (b,) = here[0][0], there[0][0]
    assert np.array_equal(a.shift, b.shift) and np.array_equal(a.shape_change, b.shape_change)
    assert np.array_equal(a.lost, b.lost)
    for ga, gb in zip(a.shares, b.shares):
        assert ga.keys() == gb.keys() and all(np.array_equal(ga[t], gb[t], equal_nan=True) for t in ga)
