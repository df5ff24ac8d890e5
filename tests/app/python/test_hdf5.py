"""Recordings as HDF5 (``export --hdf5``, Recording.to_hdf5()), read back by h5py and pandas
alone (Debian python3-h5py, python3-pandas), and by read_recording() as the same recording.

The oracles: the command line's ``export --csv`` parsed by NumPy for the ticks, h5py for the
file's structure, and the synthetic sphere's analytic signed distance for the stored volume.
"""
import json

import numpy as np
import pytest

import volume_haptics as vh
from vh_test_support import SOURCE, cli

h5py = pytest.importorskip("h5py", reason="python3-h5py is not installed (packaging/setup.sh test installs it)")

DRILL_SCENE = SOURCE / "resources/scenes/sphere-drill.json"

#: The documented HDF5 type of each tick column (recording_hdf5.h).
INTEGER_COLUMNS = {"tick": np.uint64, "contacts": np.uint32, "flags": np.uint32, "critical_segment": np.int32,
                   "removed_voxels": np.uint32, "deadline_work": np.int64}


def press_into_the_sphere():
    """Above the sphere (top at z = 20 mm) until 1 s, down to 12.5 mm by 2 s, held until 3 s:
    the spinning burr cuts."""
    keys = [(0.0, 0.030), (1.0, 0.030), (2.0, 0.0125), (3.0, 0.0125)]
    return np.array([[t, 0.0, 0.0, z, 1.0, 0.0, 0.0, 0.0] for t, z in keys])


@pytest.fixture(scope="module")
def drilled(tmp_path_factory):
    """A drilling run's recording, exported by the command line as CSV and as HDF5 with volumes."""
    d = tmp_path_factory.mktemp("h5")
    vh.run(DRILL_SCENE, press_into_the_sphere(), record=d / "drill.vhrec", lag_reference=False)
    cli("export", d / "drill.vhrec", "--csv", d / "drill.csv", "--hdf5", d / "drill.h5", "--hdf5-volume")
    return d


def test_h5py_reads_every_column_as_export_csv(drilled):
    expected = np.genfromtxt(drilled / "drill.csv", delimiter=",", names=True, dtype=np.float64)
    with open(drilled / "drill.csv") as f:
        header = f.readline().strip().split(",")
    with h5py.File(drilled / "drill.h5", "r") as f:
        assert f.attrs["vh_format"] == "VolumeHaptics recording" and f.attrs["recording_format_version"] == 5
        ticks = f["ticks"]
        assert sorted(ticks.keys()) == sorted(header)
        for column in header:
            data = ticks[column]
            assert data.shape == (len(expected),), column
            want_type = INTEGER_COLUMNS.get(column, np.float64)
            assert data.dtype == np.dtype(want_type), column
            np.testing.assert_array_equal(data[()].astype(np.float64), expected[column], err_msg=column)
            unit = data.attrs["unit"]
            suffix_unit = {"_m": "m", "_N": "N", "_Nm": "N*m", "_s": "s"}
            for suffix, u in suffix_unit.items():
                if column.endswith(suffix):
                    assert unit == u, column
        assert int(ticks["removed_voxels"][()].sum()) > 0, "the burr cut nothing: the volume checks would prove little"
        metadata = json.loads(f["metadata"][()])
        assert metadata["servo_rate_Hz"] == 1000 and json.loads(f["scene"][()]) == metadata["scene"]


def test_pandas_frame_from_h5py_alone(drilled):
    pd = pytest.importorskip("pandas")
    with h5py.File(drilled / "drill.h5", "r") as f:
        frame = pd.DataFrame({name: f["ticks"][name][()] for name in f["ticks"]})
        events = pd.DataFrame({name: f["events"][name].asstr()[()] if f["events"][name].dtype.kind == "O"
                               else f["events"][name][()] for name in f["events"]})
    reference = vh.read_recording(drilled / "drill.vhrec").dataframe()
    pd.testing.assert_frame_equal(frame[reference.columns], reference)
    assert list(events.columns) == ["t_s", "tick", "type", "detail_json"]


def test_read_recording_of_the_hdf5_is_the_recording(drilled, tmp_path):
    a = vh.read_recording(drilled / "drill.vhrec")
    b = vh.read_recording(drilled / "drill.h5")
    assert a.ticks.tobytes() == b.ticks.tobytes()
    assert (a.events, a.metadata, a.warnings) == (b.events, b.metadata, b.warnings)
    assert (a.version, a.chunks, a.event_chunks, a.dropped_records, a.bytes_ignored, a.ended, a.end_status) == \
           (b.version, b.chunks, b.event_chunks, b.dropped_records, b.bytes_ignored, b.ended, b.end_status)
    # The command line reads it too: its CSV of the HDF5 file is the .vhrec's, byte for byte.
    cli("export", drilled / "drill.h5", "--csv", tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_bytes() == (drilled / "drill.csv").read_bytes()


def test_to_hdf5_keeps_what_python_changed_and_lists_markers(drilled, tmp_path):
    rec = vh.read_recording(drilled / "drill.vhrec")
    rec.events.append({"t_s": 1.5, "tick": 1500, "type": "marker", "detail": {"label": "nerve \"V2\" \u00e9"}})
    rec.ticks = rec.ticks[::2].copy()
    assert rec.to_hdf5(tmp_path / "py.h5") == ""
    back = vh.read_recording(tmp_path / "py.h5")
    assert back.ticks.tobytes() == rec.ticks.tobytes() and back.events == rec.events
    with h5py.File(tmp_path / "py.h5", "r") as f:
        assert "volume" not in f
        assert list(f["markers/label"].asstr()[()]) == ["nerve \"V2\" \u00e9"]
        assert f["markers/tick"][0] == 1500 and f["markers/t_s"][0] == 1.5


def test_volume_is_the_scan_where_its_affine_says(drilled):
    scene = vh.load_scene(DRILL_SCENE)
    with h5py.File(drilled / "drill.h5", "r") as f:
        scan = f["volume/scan"]
        drilled_field = f["volume/drilled"][()]
        affine = scan.attrs["affine_LPS_m"]
        values = scan[()]
        removed = int(f["ticks/removed_voxels"][()].sum())
    np.testing.assert_array_equal(values, scene.volume)
    np.testing.assert_array_equal(affine, scene.affine_LPS_m)
    # The analytic oracle: the sphere's F is the signed distance [mm] to a 20 mm sphere at the
    # origin, so each voxel's value follows from where the affine puts its centre.
    ijk = np.stack(np.meshgrid(*[np.arange(n) for n in values.shape], indexing="ij"), axis=-1).reshape(-1, 3)
    points_m = ijk @ affine[:3, :3].T + affine[:3, 3]
    analytic_mm = 20.0 - 1000.0 * np.linalg.norm(points_m, axis=1)
    near = np.abs(analytic_mm) < 5.0  # the field is the distance near the surface
    np.testing.assert_allclose(values.reshape(-1)[near], analytic_mm[near], atol=1e-3)
    # The drilled field: the scan less exactly the voxels the records say the burr removed (the
    # burr's reach, air below the isovalue included), all of them now the field's lowest value.
    changed = values != drilled_field
    assert removed > 0 and int(changed.sum()) == removed
    assert np.all(drilled_field[changed] == values.min()) and np.all(values[changed] > values.min())


def test_bad_targets_and_foreign_files_are_refused_with_reasons(drilled, tmp_path):
    rec = vh.read_recording(drilled / "drill.vhrec")
    with pytest.raises(RuntimeError, match="regular file"):
        rec.to_hdf5("-")
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["ticks/t_s"] = np.arange(3.0)
    with pytest.raises(RuntimeError, match="not a VolumeHaptics recording"):
        vh.read_recording(foreign)
    # A column one row short: named, not read as a shorter recording.
    short = tmp_path / "short.h5"
    rec.to_hdf5(short)
    with h5py.File(short, "a") as f:
        force = f["ticks/force_z_N"][()]
        del f["ticks/force_z_N"]
        f["ticks/force_z_N"] = force[:-1]
    with pytest.raises(RuntimeError, match="force_z_N"):
        vh.read_recording(short)
    # A file cut anywhere is an error or the whole recording, never a crash or a silent part.
    whole = (drilled / "drill.h5").read_bytes()
    for fraction in (0.05, 0.3, 0.6, 0.9, 0.999):
        cut = tmp_path / "cut.h5"
        cut.write_bytes(whole[:int(len(whole) * fraction)])
        with pytest.raises(RuntimeError):
            vh.read_recording(cut)


def test_drilled_volume_is_the_hdf5_files_drilled_field(drilled):
    rec = vh.read_recording(drilled / "drill.vhrec")
    field, affine = rec.drilled_volume()
    with h5py.File(drilled / "drill.h5", "r") as f:
        np.testing.assert_array_equal(field, f["volume/drilled"][()])
        np.testing.assert_array_equal(affine, f["volume/drilled"].attrs["affine_LPS_m"])
    probe = vh.read_recording(drilled / "drill.vhrec")
    probe.metadata["scene"].pop("drill")
    with pytest.raises(RuntimeError, match="no drill"):
        probe.drilled_volume()
