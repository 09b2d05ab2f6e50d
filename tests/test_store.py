"""The results store: layout readable by h5py and xarray, the partial -> final protocol,
and the crash-safety premise (writing records never touches HDF5 metadata)."""

import h5py
import numpy as np
import pytest
import xarray as xr

from mcfric import store
from mcfric.store import Store, StoreError, partial_path


def make(path, n=50, nf=7, nb=3):
    coords = {"frequency": (np.linspace(10, 20, nf), {"units": "Hz"}),
              "beam": (np.arange(1, nb + 1), {})}
    variables = {"y": (("sample", "frequency", "beam"), np.complex128, {"units": "m"}),
                 "m": (("sample", "frequency"), np.float64, {}),
                 "ok": (("sample", "frequency"), np.bool_, {}),
                 "p": (("sample",), np.float64, {})}
    return Store.create(path, record_dim="sample", n_records=n, coords=coords,
                        variables=variables, attrs={"title": "t", "seed": np.int64(3)},
                        placeholders={"count": np.int64(-1), "wall": np.float64(np.nan)})


def records(a, b, nf=7, nb=3):
    rng = np.random.default_rng(a)
    y = rng.normal(size=(b - a, nf, nb)) + 1j * rng.normal(size=(b - a, nf, nb))
    return {"y": y, "m": np.abs(y).max(axis=2), "ok": np.abs(y).max(axis=2) < 2,
            "p": np.arange(a, b) * 0.5}


def raw_ranges(h5):
    """Byte ranges of every allocated chunk of every chunked dataset of an open file."""
    out = []
    for ds in h5.values():
        if isinstance(ds, h5py.Dataset) and ds.chunks is not None:
            for i in range(ds.id.get_num_chunks()):
                info = ds.id.get_chunk_info(i)
                out.append((info.byte_offset, info.byte_offset + info.size))
    return out


def test_full_protocol_and_readers(tmp_path):
    path = tmp_path / "r.h5"
    s = make(path)
    assert not path.exists() and partial_path(path).exists()
    for a in range(0, 50, 16):
        b = min(50, a + 16)
        s.write(a, records(a, b))
        s.commit([(a, b)])
    final = s.finish({"count": np.int64(4), "wall": np.float64(1.5)})
    assert final == path and path.exists() and not partial_path(path).exists()

    with h5py.File(path, "r") as h5:
        assert h5.attrs["complete"] == 1 and h5.attrs["count"] == 4
        assert h5.attrs["layout_version"] == store.LAYOUT_VERSION
        assert h5["y"].compression is None and h5["y"].chunks[1:] == (7, 3)
        np.testing.assert_array_equal(h5["y"][20:30], records(16, 32)["y"][4:14])
        assert h5["done"][...].all()
    ds = store.open_results(path)
    assert ds["y"].dims == ("sample", "frequency", "beam")
    assert ds["p"].dims == ("sample",)
    assert ds["y"].dtype == np.complex128 and ds["ok"].dtype == bool
    np.testing.assert_array_equal(ds["sample"].values, np.arange(50))
    np.testing.assert_array_equal(ds["y"].values[48:], records(48, 50)["y"])
    assert ds.frequency.attrs["units"] == "Hz" and ds.attrs["seed"] == 3
    # the other readers work while the Dataset is open (one locking flag for all)
    assert store.read_attrs(path)["count"] == 4 and "y" in store.dataset_names(path)
    ds.close()
    with xr.open_dataset(path, engine="h5netcdf") as ds2:
        assert set(ds2.dims) == {"sample", "frequency", "beam"}
        # a handle with locking on (h5py's default) is named, not called unreadable
        with pytest.raises(StoreError, match="open elsewhere in this process"):
            store.read_attrs(path)


def test_readers_refuse_arguments_they_cannot_use(tmp_path):
    """A name for a list read letter by letter, a block of -1 yielding nothing, h5py's
    IndexError or AttributeError: one line each, naming the argument."""
    path = tmp_path / "r.h5"
    s = make(path)
    s.write(0, records(0, 50))
    s.commit([(0, 50)])
    s.finish({})
    cases = [(lambda: list(store.iter_records(path, "y")), "^names: expected a list"),
             (lambda: list(store.iter_records(path, ["y"], block=-1)), "^block: expected"),
             (lambda: store.read(path, "y", row=50), r"^row: expected a record in 0\.\.49"),
             (lambda: store.read(path, "y", row=1.5), "^row:"),
             (lambda: store.open_results(path, allow_incomplete="no"), "^allow_incomplete")]
    for call, message in cases:
        with pytest.raises(StoreError, match=message):
            call()
    assert store.read(path, "y", row=49).shape == (7, 3)


def test_writing_records_never_touches_metadata(tmp_path):
    """The premise of crash safety: after creation only raw chunk bytes change."""
    path = tmp_path / "r.h5"
    nf, nb = 2000, 3                                 # ~96 kB per record: many chunks
    s = make(path, n=120, nf=nf, nb=nb)
    before = partial_path(path).read_bytes()
    ranges = raw_ranges(s._h5)
    assert len(ranges) >= 20
    written = {}
    for a in (0, 37, 70, 119):     # aligned (direct chunk writes) and unaligned edges
        b = min(120, a + 30)
        written[a, b] = records(a, b, nf, nb)
        s.write(a, written[a, b])
        s.commit([(a, b)])
    after = partial_path(path).read_bytes()
    assert raw_ranges(s._h5) == ranges          # the chunk index did not move
    for (a, b), rec in written.items():
        for name, arr in rec.items():
            assert s._h5[name][a:b].tobytes() == arr.tobytes(), (name, a, b)
    s.close()
    assert len(after) == len(before)
    keep = np.ones(len(before), bool)
    for a, b in ranges:
        keep[a:b] = False
    diff = np.frombuffer(before, np.uint8) != np.frombuffer(after, np.uint8)
    assert diff.any()                                # data did land in the file
    assert not np.any(diff & keep), "bytes outside the raw data chunks changed"


@pytest.mark.parametrize("path", [None, 3, ["r.h5"]])
def test_a_path_that_is_no_path_is_a_store_error(path):
    # h5py raised a TypeError that named no input
    for read in (store.open_results, store.read_attrs, store.describe):
        with pytest.raises(StoreError, match="^path: expected a results file's path"):
            read(path)


def test_a_directory_is_named_as_one(tmp_path):
    # HDF5's text was an errno and a time stamp
    for read in (store.open_results, store.read_attrs, store.describe,
                 lambda p: store.read_group(p, "bounds")):
        with pytest.raises(StoreError, match=f"^{tmp_path}: a directory, not a results file$"):
            read(tmp_path)


def test_a_file_like_object_is_read_as_h5py_reads_it(tmp_path):
    import io

    path = tmp_path / "r.h5"
    s = make(path, n=20)
    s.write(0, records(0, 20))
    s.commit([(0, 20)])
    final = s.finish({"count": np.int64(0), "wall": np.float64(0.0)})
    assert store.read_attrs(io.BytesIO(final.read_bytes()))["complete"] == 1


def test_partial_file_is_not_complete_and_reopens(tmp_path):
    path = tmp_path / "r.h5"
    s = make(path)
    s.write(0, records(0, 10))
    s.commit([(0, 10)])
    s.write(10, records(10, 20))                     # written, not committed
    s.close()
    assert not path.exists()
    assert store.read_attrs(partial_path(path))["complete"] == 0
    with pytest.raises(StoreError, match="incomplete"):
        store.open_results(partial_path(path))
    store.open_results(partial_path(path), allow_incomplete=True).close()
    blocks = list(store.iter_records(partial_path(path), ["p"], block=8))
    got = np.concatenate([b["p"] for _, b in blocks])
    np.testing.assert_array_equal(got, np.arange(10) * 0.5)   # only committed records
    s2 = Store.reopen(path, "sample")
    assert s2.done().sum() == 10 and s2.attrs["seed"] == 3
    s2.write(10, records(10, 50))
    s2.commit([(10, 50)])
    s2.finish({"count": np.int64(0), "wall": np.float64(0.0)})
    with h5py.File(path, "r") as h5:
        np.testing.assert_array_equal(h5["p"][...], np.arange(50) * 0.5)


def test_create_replaces_a_stale_partial_and_reopen_checks_layout(tmp_path):
    path = tmp_path / "r.h5"
    partial_path(path).write_bytes(b"not hdf5")
    with pytest.raises(StoreError):
        Store.reopen(path, "sample")
    make(path).close()
    assert store.read_attrs(partial_path(path))["complete"] == 0


def test_add_group_for_later_stages(tmp_path):
    path = tmp_path / "r.h5"
    s = make(path, n=4)
    s.write(0, records(0, 4))
    s.commit([(0, 4)])
    s.finish({"count": np.int64(0), "wall": np.float64(0.0)})
    lower, upper = np.arange(7.0), np.arange(7.0) + 1
    store.add_group(path, "bounds", {"lower": (("frequency",), lower, {"units": "m"}),
                                     "upper": (("frequency",), upper, {"units": "m"})},
                    attrs={"method": "test"})
    with xr.open_dataset(path, engine="h5netcdf", group="bounds") as g:
        assert g["upper"].dims == ("frequency",)
        np.testing.assert_array_equal(g["lower"].values, lower)
        assert g.attrs["method"] == "test"
    with pytest.raises(ValueError, match="does not match"):
        store.add_group(path, "bounds", {"x": (("frequency",), np.arange(3.0), {})})
    # the root is untouched
    with store.open_results(path) as ds:
        assert ds["y"].shape == (4, 7, 3)


def test_add_group_that_fails_midway_leaves_the_file_as_it_was(tmp_path, monkeypatch):
    """A failure after the old group was deleted and part of the new one written (here
    the second dataset's creation): the file is byte for byte as before, with its old
    group, and nothing is left beside it (in place, the old group was gone)."""
    import h5py

    path = tmp_path / "r.h5"
    s = make(path, n=4)
    s.write(0, records(0, 4))
    s.commit([(0, 4)])
    s.finish({"count": np.int64(0), "wall": np.float64(0.0)})
    store.add_group(path, "bounds", {"lower": (("frequency",), np.arange(7.0), {})})
    before = path.read_bytes()
    real, calls = h5py.Group.create_dataset, []

    def fails_second(self, *a, **k):
        calls.append(a[0] if a else k.get("name"))
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real(self, *a, **k)

    monkeypatch.setattr(h5py.Group, "create_dataset", fails_second)
    with pytest.raises(OSError, match="No space left"):
        store.add_group(path, "bounds", {"upper": (("frequency",), np.ones(7), {}),
                                         "lower": (("frequency",), np.zeros(7), {})})
    monkeypatch.undo()
    assert calls == ["upper", "lower"]                      # it failed midway
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["r.h5"]
    with h5py.File(path, "r") as h5:
        assert list(h5["bounds"]) == ["lower"]


def test_add_group_counts_the_group_in_the_room_it_needs(tmp_path, monkeypatch):
    """Room for the copy of the file but not for the group's datasets beside it (2 kB
    short of them): refused before the copy, the file untouched (the check counted the
    copy alone)."""
    import shutil
    from collections import namedtuple

    path = tmp_path / "r.h5"
    s = make(path, n=4)
    s.write(0, records(0, 4))
    s.commit([(0, 4)])
    s.finish({"count": np.int64(0), "wall": np.float64(0.0)})
    before = path.read_bytes()
    usage = namedtuple("usage", "total used free")
    group = {f"x{i}": (("frequency", "beam"), np.zeros((7, 3)), {}) for i in range(4)}
    need = len(before) + store.files.MIN_FREE + 4 * (7 * 3 * 8 + 4096)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(1 << 40, 0, need - 2048))
    with pytest.raises(StoreError, match="no space for a copy of the file"):
        store.add_group(path, "more", group)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["r.h5"]
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(1 << 40, 0, need))
    store.add_group(path, "more", group)                   # with room for both, it is added
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]
    with h5py.File(path, "r") as h5:
        assert sorted(h5["more"]) == ["x0", "x1", "x2", "x3"]


def test_reading_a_missing_or_foreign_file(tmp_path):
    with pytest.raises(StoreError, match="no such file"):
        store.read_attrs(tmp_path / "nope.h5")
    with h5py.File(tmp_path / "foreign.h5", "w") as h5:
        h5["x"] = 1
    with pytest.raises(StoreError, match="not an mcfric results file"):
        store.open_results(tmp_path / "foreign.h5")


def test_reopening_and_writing_never_touches_metadata(tmp_path):
    """Same premise on the resume path: open r+, write, commit, close."""
    path = tmp_path / "r.h5"
    nf, nb = 2000, 3
    s = make(path, n=64, nf=nf, nb=nb)
    s.write(0, records(0, 16, nf, nb))
    s.commit([(0, 16)])
    s.close()
    before = partial_path(path).read_bytes()
    s = Store.reopen(path, "sample")
    ranges = raw_ranges(s._h5)
    s.write(16, records(16, 45, nf, nb))
    s.commit([(16, 45)])
    s.close()
    after = partial_path(path).read_bytes()
    keep = np.ones(len(before), bool)
    for a, b in ranges:
        keep[a:b] = False
    diff = np.frombuffer(before, np.uint8) != np.frombuffer(after, np.uint8)
    assert diff.any() and not np.any(diff & keep)
