"""UFF import: small universal files written with pyuff, imported and checked value by value."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import pyuff

from jointid.errors import DataError
from jointid.data.dataset import read_dataset
from jointid.data.uff import import_uff, main, map_nodes, modes_from_frf

POINTS = pd.DataFrame({"point": ["T01", "T02", "B01", "B02"],
                       "x_m": [0.0, 0.1, 0.0, 0.1], "y_m": [0.2, 0.2, 0.0, 0.0],
                       "z_m": [0.0, 0.0, 0.3, 0.3]})
# UFF nodes in mm: 101 = T01, 102 = T02, 103 = B01 (1 mm off), 999 far away; B02 has no node
NODES_MM = {101: (0.0, 200.0, 0.0), 102: (100.0, 200.0, 0.0), 103: (1.0, 0.0, 300.0),
            999: (500.0, 500.0, 500.0)}
MODES = [(1800.0, 0.03), (350.0, 0.01), (1200.0, 0.02)]  # written out of frequency order
SHAPE = {101: (0.1, 1.0, 0.0), 102: (0.2, -0.5, 0.05), 103: (0.0, 0.3, 0.0), 999: (9.0, 9.0, 9.0)}


def _nodes(ids, xyz, kind=2411):
    ids = np.array(ids, dtype=int)
    xyz = np.asarray(xyz, float)
    if kind == 15:
        return pyuff.prepare_15(node_nums=ids, def_cs=np.zeros_like(ids), disp_cs=np.zeros_like(ids),
                                color=np.ones_like(ids), x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])
    return pyuff.prepare_2411(node_nums=ids, def_cs=np.zeros_like(ids), disp_cs=np.zeros_like(ids),
                              color=np.ones_like(ids), x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])


def _mode(k, freq, zeta, shape):
    ids = np.array(sorted(shape), dtype=int)
    r = np.array([shape[i] for i in ids], float) * (k + 1)
    return pyuff.prepare_55(model_type=1, id1=f"mode {k + 1}", analysis_type=2, data_ch=2,
                            spec_data_type=8, data_type=2, r1=r[:, 0], r2=r[:, 1], r3=r[:, 2],
                            n_data_per_node=3, node_nums=ids, load_case=1, mode_n=k + 1,
                            modal_m=0.0, freq=freq, modal_damp_vis=zeta, modal_damp_his=0.0)


def _frf(f, data, rsp_node, rsp_dir, ref_node, ref_dir, ordinate=12, func_type=4):
    return pyuff.prepare_58(func_type=func_type, rsp_node=rsp_node, rsp_dir=rsp_dir,
                            ref_node=ref_node, ref_dir=ref_dir, data=data, x=f,
                            id1=f"H {rsp_node}/{ref_node}", ord_data_type=6, abscissa_spacing=1,
                            abscissa_min=float(f[0]), abscissa_inc=float(f[1] - f[0]),
                            num_pts=len(f), ordinate_spec_data_type=ordinate,
                            orddenom_spec_data_type=13, abscissa_spec_data_type=18,
                            rsp_ent_name="resp", ref_ent_name="ref")


def _sdof_receptance(f, fn=800.0, zeta=0.02, k=2.0e7):
    r = f / fn
    return 1.0 / (k * (1 - r**2 + 2j * zeta * r))


def write_uff(path, *, units=True, frf=True, nodes=NODES_MM):
    sets = []
    if units:
        sets.append(pyuff.prepare_164(units_code=5, units_description="mm (milli newton)",
                                      temp_mode=1, length=1000.0, force=1000.0, temp=1.0,
                                      temp_offset=273.15))
    if nodes:
        sets.append(_nodes(list(nodes), list(nodes.values())))
    sets += [_mode(k, f, z, SHAPE) for k, (f, z) in enumerate(MODES)]
    if frf:
        f = np.linspace(0.0, 2000.0, 201)
        acc = -(2 * np.pi * f) ** 2 * _sdof_receptance(f)  # accelerance (m/s^2)/N = (mm/s^2)/mN
        sets.append(_frf(f, acc, 102, -2, 101, 2))
        sets.append(_frf(f, acc, 102, 1, 101, 2, func_type=1))  # a time response: skipped
    writer = pyuff.UFF(str(path))
    writer.write_sets(sets, mode="overwrite")
    return path


def test_import_frequencies_damping_renumbered(tmp_path):
    ds, report = import_uff(write_uff(tmp_path / "t.unv"), POINTS, state="power_off")
    np.testing.assert_allclose(ds.freqs("power_off"), [350.0, 1200.0, 1800.0])
    np.testing.assert_allclose(ds.damping("power_off"), [0.01, 0.02, 0.03])
    assert "UFF 55 mode numbers were renumbered 1..n in order of frequency" in report


def test_import_node_mapping_and_unmatched_lines(tmp_path):
    _, report = import_uff(write_uff(tmp_path / "t.unv"), POINTS, state="s")
    assert "UFF node 999 not matched: nearest point B02 is 0.6708 m away (tol_m = 0.005)" in report
    assert "1 measuring point(s) have no UFF node: B02" in report
    assert not any("node 101" in line or "node 103" in line for line in report)


def test_import_shape_values_at_mapped_points(tmp_path):
    ds, _ = import_uff(write_uff(tmp_path / "t.unv"), POINTS, state="s")
    # mode 1 (350 Hz) was UFF mode 2: values x2; mode 3 (1800 Hz) was UFF mode 1: values x1
    phi = ds.shape_matrix("s", ["T01:y", "T02:x", "T02:y", "B01:y", "B02:y"])
    np.testing.assert_allclose(phi[:4], [[2.0, 3.0, 1.0], [0.4, 0.6, 0.2], [-1.0, -1.5, -0.5],
                                         [0.6, 0.9, 0.3]])
    assert np.isnan(phi[4]).all()
    assert set(ds.shapes["point"]) == {"T01", "T02", "B01"}


def test_import_frf_converted_to_receptance(tmp_path):
    ds, report = import_uff(write_uff(tmp_path / "t.unv"), POINTS, state="s")
    f, h = ds.frf_curve("s", "T02", "y")
    assert f[0] == pytest.approx(10.0) and len(f) == 200  # the 0 Hz line is dropped
    # response direction -Y: sign flipped; accelerance / -(2 pi f)^2 = receptance; mm/mN = m/N
    np.testing.assert_allclose(h, -_sdof_receptance(f), rtol=1e-4)
    assert ds.state_conditions("s")["frf_drive_point"] == "T01"
    assert ds.state_conditions("s")["frf_drive_direction"] == "y"
    assert any("function type 1 is not an FRF; skipped" in line for line in report)
    assert any("1 line(s) at 0 Hz dropped" in line for line in report)


def test_import_writes_valid_dataset_and_merges_states(tmp_path):
    path = write_uff(tmp_path / "t.unv")
    out = tmp_path / "data" / "mytest"
    import_uff(path, POINTS, state="power_off", out=out, em_force_N=0.0)
    ds, _ = import_uff(path, POINTS, state="power_on", out=out, em_force_N=1000.0, merge=True)
    assert ds.states == ["power_off", "power_on"]
    again = read_dataset(out, POINTS, expected_states=["power_off", "power_on"])
    assert again.state_conditions("power_on")["em_force_N"] == 1000.0
    assert len(again.shapes) == 2 * 3 * 3 * 3 and len(again.frf) == 2 * 200
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["mytest"]


def test_em_force_default_is_reported(tmp_path):
    ds, report = import_uff(write_uff(tmp_path / "t.unv", frf=False), POINTS, state="s")
    assert ds.state_conditions("s") == {"em_force_N": 0.0}
    assert ds.frf is None
    assert any("em_force_N of state s not given; 0.0 written" in line for line in report)


def test_length_scale_without_units_dataset(tmp_path):
    path = write_uff(tmp_path / "t.unv", units=False, frf=False)
    with pytest.raises(DataError) as info:  # no node matches in metres: every shape would be dropped
        import_uff(path, POINTS, state="s")
    lines = info.value.problems
    assert "every mode shape was dropped" in lines[0] and "--node-map" in lines[0]
    assert any("coordinates look like mm" in line for line in lines)
    assert "4 measuring point(s) have no UFF node: T01, T02, B01, B02" in lines
    ds, report = import_uff(path, POINTS, state="s", length_scale=0.001)
    assert set(ds.shapes["point"]) == {"T01", "T02", "B01"}
    assert not any("look like mm" in line for line in report)


def test_units_dataset_wins_over_length_scale(tmp_path):
    _, report = import_uff(write_uff(tmp_path / "t.unv", frf=False), POINTS, state="s",
                           length_scale=1.0)
    assert any("length_scale = 1 ignored" in line for line in report)


def test_name_matching_by_number_suffix_and_ambiguity():
    nodes = pd.DataFrame({"node": [7, 5, 3], "x_m": np.nan, "y_m": np.nan, "z_m": np.nan})
    points = pd.DataFrame({"point": ["T07", "T05", "B05", "B03"], "x_m": 0.0, "y_m": 0.0,
                           "z_m": 0.0})
    mapping, report = map_nodes(nodes, points, node_map={3: "B03"})
    assert mapping == {7: "T07", 3: "B03"}
    assert "UFF node 5 not matched: no coordinates and no point name ending in that number" \
        in report


def test_name_match_far_from_coordinates_is_flagged():
    nodes = pd.DataFrame({"node": [7], "x_m": [1.0], "y_m": [0.0], "z_m": [0.0]})
    points = pd.DataFrame({"point": ["T07"], "x_m": [0.0], "y_m": [0.0], "z_m": [0.0]})
    mapping, report = map_nodes(nodes, points)
    assert mapping == {7: "T07"}
    assert report == ["UFF node 7 mapped to T07 by name although it is 1 m from that point; "
                      "check the numbering"]


def test_two_nodes_on_one_point_keep_the_closer():
    nodes = pd.DataFrame({"node": [21, 22], "x_m": [0.003, 0.001], "y_m": 0.0, "z_m": 0.0})
    points = pd.DataFrame({"point": ["P"], "x_m": [0.0], "y_m": [0.0], "z_m": [0.0]})
    mapping, report = map_nodes(nodes, points)
    assert mapping == {22: "P"}
    assert report == ["UFF node 21 not matched: point P is already taken by the closer node 22"]


def test_complex_modes_give_frequency_damping_and_real_shape(tmp_path):
    fn, zeta = 640.0, 0.05
    wn = 2 * np.pi * fn
    lam = complex(-zeta * wn, wn * np.sqrt(1 - zeta**2))
    phase = np.exp(1j * 0.7)
    ids = np.array([101, 102])
    sets = [_nodes(ids, [NODES_MM[101], NODES_MM[102]], kind=15),
            pyuff.prepare_55(model_type=1, id1="cplx", analysis_type=3, data_ch=2,
                             spec_data_type=8, data_type=5, r1=np.array([1.0, 2.0]) * phase,
                             r2=np.array([-1.0, 0.5]) * phase, r3=np.zeros(2, complex),
                             n_data_per_node=3, node_nums=ids, load_case=1, mode_n=1, eig=lam,
                             modal_a=0j, modal_b=0j)]
    pyuff.UFF(str(tmp_path / "c.unv")).write_sets(sets, mode="overwrite")
    ds, _ = import_uff(tmp_path / "c.unv", POINTS, state="s", length_scale=0.001)
    assert ds.freqs("s")[0] == pytest.approx(fn, rel=1e-4)
    assert ds.damping("s")[0] == pytest.approx(zeta, rel=1e-3)
    phi = ds.shape_matrix("s", ["T01:x", "T02:x", "T01:y", "T02:y"])[:, 0]
    phi = phi * np.sign(phi[0])
    np.testing.assert_allclose(phi, [1.0, 2.0, -1.0, 0.5], atol=1e-4)


def test_file_without_modes_or_unreadable(tmp_path):
    pyuff.UFF(str(tmp_path / "n.unv")).write_sets([_nodes([101], [NODES_MM[101]])],
                                                   mode="overwrite")
    with pytest.raises(DataError, match=r"no mode shapes \(dataset 55\) found"):
        import_uff(tmp_path / "n.unv", POINTS, state="s")
    with pytest.raises(DataError, match="UFF file does not exist"):
        import_uff(tmp_path / "missing.unv", POINTS, state="s")


def test_cli_writes_dataset(tmp_path, capsys):
    path = write_uff(tmp_path / "t.unv")
    POINTS.to_csv(tmp_path / "measuring_points.csv", index=False)
    code = main([str(path), "--state", "power_off", "--points",
                 str(tmp_path / "measuring_points.csv"), "--out", str(tmp_path / "mytest"),
                 "--em-force-N", "0"])
    assert code == 0
    captured = capsys.readouterr()
    assert "UFF node 999 not matched" in captured.err
    assert "3 modes, states power_off" in captured.out
    assert read_dataset(tmp_path / "mytest", POINTS).freqs("power_off")[0] == pytest.approx(350.0)
    assert main([str(tmp_path / "nope.unv"), "--state", "s", "--points",
                 str(tmp_path / "measuring_points.csv"), "--out", str(tmp_path / "x")]) == 2
    capsys.readouterr()
    assert main([str(path), "--state", "s", "--points", str(tmp_path / "none.csv"), "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert "measuring-points file not found — the mesh rule writes it" in err and "Errno" not in err


def test_modes_from_frf_recovers_frequency_and_damping():
    f = np.arange(1.0, 4000.0, 0.05)
    # f_n, zeta, residue: each peak dominates its band (the other modes' tails bias peak picking,
    # e.g. by 0.4 % for a weak third mode with zeta = 0.03)
    modal = [(500.0, 0.02, 1.0), (1500.0, 0.01, 1.0), (2900.0, 0.015, 2.0)]
    h = sum(a / ((2 * np.pi * fn) ** 2 - (2 * np.pi * f) ** 2
                 + 2j * z * (2 * np.pi * fn) * (2 * np.pi * f)) for fn, z, a in modal)
    picked = modes_from_frf(f, h, 3)
    assert list(picked["mode"]) == [1, 2, 3]
    for (fn, z, _), (_, row) in zip(modal, picked.iterrows()):
        assert row["freq_Hz"] == pytest.approx(fn * np.sqrt(1 - 2 * z**2), rel=1e-3)
        assert row["damping_ratio"] == pytest.approx(z, rel=0.01)
    two = modes_from_frf(f, np.column_stack([h, 2 * h]), 2)  # the two most prominent peaks
    np.testing.assert_allclose(two["freq_Hz"], picked["freq_Hz"][:2], rtol=1e-6)


# ---------------------------------------------------------------- real files not written here
REAL = Path(__file__).parent / "data" / "uff"


def named_points(nodes) -> pd.DataFrame:
    """Measuring points named after the file's node numbers (matched by name), far apart."""
    nodes = list(nodes)
    return pd.DataFrame({"point": [f"P{n}" for n in nodes], "part": "table",
                         "x_m": np.arange(len(nodes), dtype=float), "y_m": 0.0, "z_m": 0.0})


def test_real_normal_modes_import_in_hz(tmp_path):
    """Modes at 10-13 Hz are not taken for kHz: UFF 55 frequencies are Hz by definition."""
    ds, report = import_uff(REAL / "uff55_translation.uff", named_points([1, 2, 3, 4]), state="s",
                            out=tmp_path / "ds")
    assert ds.freqs("s") == pytest.approx([10.0, 12.0, 13.0])
    assert ds.conditions["frequencies_in_Hz_confirmed"] is True
    assert set(ds.shapes["point"]) == {"P1", "P2", "P3", "P4"}


def test_real_complex_mode_is_made_real_and_said(tmp_path):
    ds, report = import_uff(REAL / "uff55_sample_test_record10.uff", named_points([111111, 60101]), state="s",
                            out=tmp_path / "ds")
    lam = complex(-0.1111111, 41.11111)
    assert ds.freqs("s") == pytest.approx([abs(lam) / (2 * np.pi)])
    assert ds.modes["damping_ratio"].iloc[0] == pytest.approx(-lam.real / abs(lam))
    assert any("complex shape made real" in line for line in report)


def test_real_six_dof_shapes_keep_the_translations(tmp_path):
    ds, report = import_uff(REAL / "uff55_translation_rotation.uff", named_points(range(1, 44)), state="s",
                            out=tmp_path / "ds")
    assert ds.freqs("s") == pytest.approx([97.013])
    assert len(set(ds.shapes["point"])) == 43
    assert any("rotations r4, r5, r6 dropped" in line for line in report)


def test_real_geometry_only_export_is_refused_in_a_few_lines(tmp_path):
    """A Test.Lab geometry export (no modes): the right message, and the 36 unmatched nodes summed up."""
    with pytest.raises(DataError) as info:
        import_uff(REAL / "TestLab_161_164_18_15_82.uff", POINTS, state="s", out=tmp_path / "ds")
    lines = info.value.problems
    assert "no mode shapes (dataset 55) found" in lines[0]
    assert len(lines) <= 8 and any("UFF nodes not matched in all" in line for line in lines), lines
    assert not (tmp_path / "ds").exists()


def test_every_shape_dropped_is_an_error_unless_mapped_or_frequencies_only(tmp_path, capsys):
    path = REAL / "uff55_translation.uff"
    far = named_points([1, 2, 3, 4]).assign(point=["A", "B", "C", "D"])  # no name ends in a node number
    with pytest.raises(DataError, match="every mode shape was dropped"):
        import_uff(path, far, state="s", out=tmp_path / "a")
    assert not (tmp_path / "a").exists()
    pd.DataFrame({"node": [1, 2, 3, 4], "point": ["A", "B", "C", "D"]}).to_csv(tmp_path / "map.csv", index=False)
    far.to_csv(tmp_path / "points.csv", index=False)
    args = [str(path), "--state", "s", "--points", str(tmp_path / "points.csv")]
    assert main(args + ["--out", str(tmp_path / "b")]) == 2
    assert "every mode shape was dropped" in capsys.readouterr().err
    assert main(args + ["--out", str(tmp_path / "c"), "--node-map", str(tmp_path / "map.csv")]) == 0
    assert set(read_dataset(tmp_path / "c").shapes["point"]) == {"A", "B", "C", "D"}
    assert main(args + ["--out", str(tmp_path / "d"), "--frequencies-only"]) == 0
    assert read_dataset(tmp_path / "d").shapes is None


def test_frf_only_file_gives_modes_by_peak_picking(tmp_path):
    """A file with FRFs (dataset 58) and no modes: --modes-from-frf N picks them (written here with
    pyuff: a two-mode receptance)."""
    f = np.linspace(50.0, 400.0, 1401)
    w = 2 * np.pi * f
    H = sum(1.0 / ((2 * np.pi * fn) ** 2 - w ** 2 + 2j * 0.02 * 2 * np.pi * fn * w) for fn in (120.0, 260.0))
    path = tmp_path / "frf.uff"
    uff = pyuff.UFF(str(path))
    uff.write_sets([pyuff.prepare_58(binary=0, id1="drive point", func_type=4, rsp_node=1, rsp_dir=2,
                                     ref_node=1, ref_dir=2, data=H, x=f, abscissa_spec_data_type=18,
                                     ordinate_spec_data_type=8, orddenom_spec_data_type=13)], mode="overwrite")
    with pytest.raises(DataError, match="--modes-from-frf N"):
        import_uff(path, named_points([1]), state="s")
    ds, report = import_uff(path, named_points([1]), state="s", out=tmp_path / "ds", n_frf_modes=2)
    assert ds.freqs("s") == pytest.approx([120.0, 260.0], rel=2e-3)
    assert ds.frf is not None and any("picked from 1 FRF" in line for line in report)
