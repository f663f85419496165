"""Memory-mappable .npz: aligned writing, mapping without a copy, fallback for other .npz files."""

import mmap
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from jointid import io
from jointid.config.typed import ModelSpec

DTYPES = [np.float64, np.float32, np.int32, np.int64, np.uint8, np.bool_, np.complex128]


def _mapped(a: np.ndarray) -> bool:
    """Whether ``a`` is a view of a memory map (no copy of its own)."""
    while a is not None and not isinstance(a, mmap.mmap):
        if isinstance(a, np.ndarray) and a.flags.owndata:
            return False
        a = a.obj if isinstance(a, memoryview) else a.base
    return isinstance(a, mmap.mmap)


@settings(max_examples=25, deadline=None)
@given(arrays=st.lists(hnp.arrays(st.sampled_from(DTYPES), hnp.array_shapes(min_dims=0, max_dims=3, max_side=7)),
                       min_size=1, max_size=5))
def test_round_trip_is_exact_aligned_and_mapped(tmp_path_factory, arrays):
    path = tmp_path_factory.mktemp("npz") / "a.npz"
    named = {f"group/{i}": a for i, a in enumerate(arrays)}
    io.write_npz_mappable(path, named)
    plain = np.load(path)  # an ordinary .npz for numpy
    mapped = io.map_npz(path)
    assert set(mapped) == set(named) == set(plain.files)
    for k, a in named.items():
        for got in (plain[k], mapped[k]):
            assert got.dtype == a.dtype and got.shape == a.shape
            assert np.array_equal(got, a, equal_nan=a.dtype.kind in "fc")
        assert _mapped(mapped[k]) and not mapped[k].flags.writeable
        assert mapped[k].ctypes.data % io.NPZ_ALIGN == 0 or mapped[k].nbytes == 0


def test_fortran_ordered_and_string_arrays(tmp_path):
    f = np.asfortranarray(np.arange(12.0).reshape(3, 4))
    s = np.array(["x", "yy", "zzz"])
    io.write_npz_mappable(tmp_path / "a.npz", {"f": f, "s": s})
    m = io.map_npz(tmp_path / "a.npz")
    assert np.array_equal(m["f"], f) and np.array_equal(m["s"], s)


def test_other_npz_files_are_read_as_numpy_reads_them(tmp_path):
    a, b = np.arange(10.0), np.arange(5, dtype=np.int32)
    np.savez(tmp_path / "plain.npz", a=a, b=b)
    np.savez_compressed(tmp_path / "packed.npz", a=a, b=b)
    for name in ("plain.npz", "packed.npz"):
        m = io.map_npz(tmp_path / name)
        assert np.array_equal(m["a"], a) and np.array_equal(m["b"], b)
    with zipfile.ZipFile(tmp_path / "packed.npz") as zf:
        assert all(i.compress_type == zipfile.ZIP_DEFLATED for i in zf.infolist())


def test_object_arrays_are_refused(tmp_path):
    with pytest.raises(ValueError, match="Python objects"):
        io.write_npz_mappable(tmp_path / "a.npz", {"o": np.array([{}, []], dtype=object)})
    assert not (tmp_path / "a.npz").exists()


def test_saved_model_loads_mapped_and_solves_the_same(tmp_path):
    from conftest import coarse_config_dict
    from jointid.config import load_config
    from jointid.fe.modal import solve_model
    from jointid.fe.model import base_coefficients, build_model, load_model, save_model

    cfg = load_config(coarse_config_dict())
    model = build_model(ModelSpec.from_config(cfg))
    save_model(model, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    assert _mapped(loaded.stiffness["K0"].data) and _mapped(loaded.mass["M0"].indices)
    for name, A in model.stiffness.items():
        assert (A != loaded.stiffness[name]).nnz == 0
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model)
    a, b = solve_model(model, kc, mc, 6), solve_model(loaded, kc, mc, 6)
    assert np.allclose(a.freqs_Hz, b.freqs_Hz, rtol=1e-10)


def _resident_kB(a: np.ndarray) -> int:
    """Resident kB of the mapping that holds ``a``'s data (its entry in /proc/self/smaps)."""
    addr = a.__array_interface__["data"][0]
    inside = False
    with open("/proc/self/smaps") as fh:
        for line in fh:
            head = line.split()[0]
            if "-" in head and not head.endswith(":"):
                lo, hi = (int(x, 16) for x in head.split("-"))
                inside = lo <= addr < hi
            elif inside and head == "Rss:":
                return int(line.split()[1])
    raise AssertionError("no mapping holds the array")


@pytest.mark.skipif(not hasattr(mmap, "MADV_DONTNEED") or not __import__("os").path.exists("/proc/self/smaps"),
                    reason="needs madvise and /proc/self/smaps (Linux)")
def test_released_pages_leave_the_process_and_come_back_unchanged(tmp_path):
    a = np.arange(2_000_000, dtype=np.float64)  # 16 MB: many pages
    io.write_npz_mappable(tmp_path / "a.npz", {"a": a, "b": a[:10].copy()})
    mapped = io.map_npz(tmp_path / "a.npz")
    total = float(mapped["a"].sum())  # touches every page
    assert _resident_kB(mapped["a"]) >= 15_000
    assert io.release_mapped([mapped["a"], mapped["b"]]) == 1  # one file, one map
    assert _resident_kB(mapped["a"]) < 1_000
    assert float(mapped["a"].sum()) == total and np.array_equal(mapped["b"], a[:10])
    assert io.release_mapped([a, np.zeros(3)]) == 0  # arrays of their own: nothing to release


def test_a_solve_releases_the_model_file_and_leaves_the_model_unchanged(tmp_path):
    from conftest import coarse_config_dict
    from jointid.config import load_config
    from jointid.fe.modal import solve_model
    from jointid.fe.model import base_coefficients, build_model, load_model, save_model

    cfg = load_config(coarse_config_dict())
    save_model(build_model(ModelSpec.from_config(cfg)), tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), loaded)
    first = solve_model(loaded, kc, mc, 6)
    if hasattr(mmap, "MADV_DONTNEED") and __import__("os").path.exists("/proc/self/smaps"):
        assert _resident_kB(loaded.stiffness["K0"].data) < 0.1 * loaded.stiffness["K0"].data.nbytes / 1024
    again = solve_model(loaded, kc, mc, 6)  # the released pages are read back as they were
    assert np.array_equal(first.freqs_Hz, again.freqs_Hz)
