"""The Python module against the command line: the same run gives the same ticks as
`volume-haptics run` (read from `export --csv` with NumPy's own CSV parser), a recording read in
Python equals `export --csv` column for column, the session metrics equal `report --table`, and
errors carry the command line's messages. Run by ctest (python.pytest) with VH_CLI naming the
built volume-haptics, VH_SOURCE_DIR the source tree and PYTHONPATH the built module.
"""
import csv
import math
import threading
import time

import numpy as np
import pytest

import volume_haptics as vh
from vh_test_support import SOURCE, cli

SCENE = SOURCE / "resources/scenes/sphere-probe.json"


def csv_columns(path):
    """A CSV with a header as {column: float64 array}, parsed by NumPy (not by the module)."""
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=np.float64)
    return {n: np.atleast_1d(data[n]) for n in data.dtype.names}


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A push-and-slide trajectory from `make-trajectory`, sped up 5 times (about 1000 ticks),
    run once by the command line with --record, and that recording exported as CSV."""
    d = tmp_path_factory.mktemp("vh")
    cli("make-trajectory", "--scene", SCENE, "--out", d / "slow.csv")
    t = vh.read_trajectory(d / "slow.csv")
    t[:, 0] *= 0.2
    vh.write_trajectory(d / "t.csv", t)
    cli("run", "--scene", SCENE, "--trajectory", d / "t.csv", "--record", d / "cli.vhrec", "--report", d / "cli.json")
    cli("export", d / "cli.vhrec", "--csv", d / "cli.csv", "--events-csv", d / "events.csv")
    return d


def test_run_gives_the_command_lines_ticks(work):
    result = vh.run(SCENE, vh.read_trajectory(work / "t.csv"))
    expected = csv_columns(work / "cli.csv")
    n = len(expected["tick"])
    assert n > 500 and len(result.ticks) == n
    assert result.contacts.max() > 0, "the trajectory never touches: the comparison would prove little"
    for column, values in expected.items():
        if column == "tick_time_s":  # the solver's compute time: a clock, not a result
            continue
        np.testing.assert_array_equal(result.ticks[column].astype(np.float64), values, err_msg=column)
    # The convenience arrays are the same columns, in the documented order.
    np.testing.assert_array_equal(result.force_N, np.column_stack([expected["force_x_N"], expected["force_y_N"],
                                                                   expected["force_z_N"]]))
    np.testing.assert_array_equal(result.proxy_pose[:, 3], expected["proxy_qw"])
    assert result.device_pose.shape == (n, 7) and result.torque_Nm.shape == (n, 3)
    import json
    cli_report = json.loads((work / "cli.json").read_text())
    for key in ("ticks", "max_contacts", "ticks_in_contact", "max_force_N", "max_penetration_m", "crossings"):
        assert result.report[key] == cli_report[key], key


def test_read_recording_equals_export_csv(work):
    rec = vh.read_recording(work / "cli.vhrec")
    expected = csv_columns(work / "cli.csv")
    assert len(rec.ticks) == len(expected["t_s"]) and not rec.warnings
    for column, values in expected.items():
        np.testing.assert_array_equal(rec.ticks[column].astype(np.float64), values, err_msg=column)
    with open(work / "events.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(e["tick"], e["type"]) for e in rec.events] == [(int(r["tick"]), r["type"]) for r in rows]
    assert rec.scene is not None and rec.metadata["servo_rate_Hz"] == 1000


def test_dataframe_when_pandas_is_installed(work):
    pd = pytest.importorskip("pandas")
    frame = vh.read_recording(work / "cli.vhrec").dataframe()
    with open(work / "cli.csv") as f:
        assert list(frame.columns) == f.readline().strip().split(",")
    np.testing.assert_array_equal(frame["force_z_N"].to_numpy(), csv_columns(work / "cli.csv")["force_z_N"])
    assert isinstance(frame, pd.DataFrame)


def test_session_metrics_equal_report_table(work, tmp_path):
    folder = tmp_path / "cohort"
    folder.mkdir()
    (folder / "a.vhrec").write_bytes((work / "cli.vhrec").read_bytes())
    cli("report", folder, "--table", tmp_path / "table.csv")
    with open(tmp_path / "table.csv", newline="") as f:
        row = next(csv.DictReader(f))
    metrics = vh.session_metrics(folder / "a.vhrec")
    compared = 0
    for key, text in row.items():
        if key in ("file", "notices") or key not in metrics:
            continue
        if isinstance(metrics[key], str):
            assert metrics[key] == text, key
        else:
            assert math.isclose(metrics[key], float(text), rel_tol=1e-8, abs_tol=1e-12), key
        compared += 1
    assert compared > 20 and metrics["time_in_contact_s"] > 0


def test_scene_dict_and_loaded_scene(work):
    """A dict with a scene file's keys loads like the file; a stiffer coupling pushes harder."""
    t = vh.read_trajectory(work / "t.csv")
    base = {"volume": {"path": "builtin:sphere", "isovalue": 0},
            "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.001}}
    forces = []
    for k in (500.0, 2000.0):
        scene = vh.load_scene(dict(base, coupling={"linear_N_per_m": k, "angular_Nm_per_rad": 1.0}))
        assert scene.volume_dims == [64, 64, 64] and scene.source == "scene dict"
        forces.append(np.linalg.norm(vh.run(scene, t, verify_step_voxels=0, lag_reference=False).force_N, axis=1).max())
    assert forces[1] > 2.0 * forces[0]


def test_tool_fit_flags_a_tool_too_costly_and_offers_a_coarser_spacing():
    """The fit check at a given cost of a work unit (the verdict the same on every machine): free, the
    probe fits; at a cost that puts its heaviest warm-up tick at twice the deadline, it is late and a
    coarser spacing that fits at that cost is offered, with how closely it is felt."""
    scene = vh.load_scene({"volume": {"path": "builtin:sphere", "isovalue": 0},
                           "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.0005}})
    free = scene.tool_fit(ns_per_work=1e-3)
    assert free["fits"] and free["cut_ticks"] == 0 and free["suggested_spacing_m"] is None
    assert free["work_max"] > 0 and free["points"] > 0 and free["spacing_m"] == pytest.approx(0.0005, rel=0.3)
    costly = scene.tool_fit(ns_per_work=2.0 * 900e3 / free["work_max"])
    assert not costly["fits"] and costly["cut_ticks"] > costly["ticks"] / 1000
    assert "late" in costly["summary"]
    assert costly["suggested_spacing_m"] is not None and costly["suggested_spacing_m"] > free["spacing_m"]
    assert costly["suggested_points"] < free["points"] and costly["suggested_felt_gap_m"] > 0
    measured = scene.tool_fit()  # this computer's cost, measured: a figure, not judged here
    assert measured["ns_per_work"] > 0 and measured["warmup_s"] > 0


def test_gil_is_released_while_running(work):
    t = vh.read_trajectory(work / "slow.csv")  # about 5000 ticks
    scene = vh.load_scene(SCENE)
    done, span = [], []

    def run():
        start = time.monotonic()
        done.append(vh.run(scene, t))
        span.extend((start, time.monotonic()))

    worker = threading.Thread(target=run)
    worker.start()
    stamps = []
    while worker.is_alive():
        stamps.append(time.monotonic())  # Python bytecode: runs only while the run holds no GIL
        time.sleep(0.001)
    worker.join()
    assert done and len(span) == 2
    # Counted within the run's own start and end, not against a guess of how long it takes: a
    # run that held the GIL would let in at most the pass of a GIL switch just before the call.
    inside = sum(span[0] < s < span[1] for s in stamps)
    assert inside >= 3, "%d of %d passes during the %.3f s run" % (inside, len(stamps), span[1] - span[0])


def test_errors_carry_the_command_lines_messages(work, tmp_path):
    missing = tmp_path / "missing.json"
    p = cli("run", "--scene", missing, "--trajectory", work / "t.csv", check=False)
    with pytest.raises(RuntimeError) as e:
        vh.run(missing, work / "t.csv")
    assert p.stderr.strip().splitlines()[-1] == "volume-haptics: error: " + str(e.value)

    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0,0,0,0,1,0,0,zero\n")
    p = cli("run", "--scene", SCENE, "--trajectory", bad, check=False)
    with pytest.raises(RuntimeError) as e:
        vh.run(SCENE, bad)
    assert p.stderr.strip().splitlines()[-1] == "volume-haptics: error: " + str(e.value)

    broken = tmp_path / "broken.nii"
    broken.write_bytes(b"\x5c\x01\x00\x00" + bytes(100))
    scene_file = tmp_path / "broken.json"
    scene_file.write_text('{"volume": {"path": "%s"}, "tool": {"mesh": "builtin:probe"}}' % broken)
    p = cli("run", "--scene", scene_file, "--trajectory", work / "t.csv", check=False)
    with pytest.raises(vh.LoadError) as e:
        vh.run(scene_file, work / "t.csv")
    assert "truncated NIfTI-1 header" in str(e.value)
    assert p.stderr.strip().splitlines()[-1] == "volume-haptics: error: " + str(e.value)

    with pytest.raises(ValueError, match=r"\(N, 8\) or \(N, 9\)"):
        vh.run(SCENE, np.zeros((3, 7)))


def test_trajectory_round_trip(tmp_path):
    t = np.array([[0.0, 0.01, 0.02, 0.03, 1, 0, 0, 0, np.nan], [0.5, 0.011, 0.02, 0.03, 0, 1, 0, 0, 42.5]])
    vh.write_trajectory(tmp_path / "t.csv", t)
    back = vh.read_trajectory(tmp_path / "t.csv")
    np.testing.assert_array_equal(back, t)
    with open(tmp_path / "t.csv") as f:
        assert f.readline().strip() == "t_s,x_m,y_m,z_m,qw,qx,qy,qz,isovalue"
    with pytest.raises(ValueError):
        vh.write_trajectory(tmp_path / "u.csv", t[::-1])  # times must increase


def test_scene_volume_is_where_nibabel_puts_it(tmp_path):
    """Scene.volume and affine_LPS_m against nibabel (an independent reader) on an oblique,
    scaled NIfTI: at every voxel of the array, the world point the affine gives lands on a voxel
    centre of nibabel's affine and holds nibabel's value there (get_fdata(), scl_slope and
    scl_inter applied)."""
    nib = pytest.importorskip("nibabel")
    shape = (12, 9, 7)
    i, j, k = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    raw = (1 + i + 10 * j + 100 * k).astype(np.int16)
    a = math.radians(20.0)
    R = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    A = np.eye(4)
    A[:3, :3] = R @ np.diag([0.8, 1.1, 2.5])
    A[:3, 3] = [-30.0, 12.0, 4.0]
    img = nib.Nifti1Image(raw, A)
    img.header.set_xyzt_units("mm")
    img.header.set_slope_inter(0.5, -10.0)
    img.set_qform(A, code=1)
    img.set_sform(A, code=1)
    path = tmp_path / "oblique.nii.gz"
    nib.save(img, str(path))

    scene = vh.load_scene({"volume": {"path": str(path), "isovalue": 100},
                           "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.001}})
    values = scene.volume
    affine = np.asarray(scene.affine_LPS_m)
    assert values.shape == tuple(scene.volume_dims)
    assert affine.shape == (4, 4) and np.allclose(affine[3], [0, 0, 0, 1])
    assert np.allclose(np.asarray(scene.direction_LPS) @ np.diag(scene.volume_spacing_m), affine[:3, :3])

    theirs = nib.load(str(path))
    their_values = theirs.get_fdata()
    to_their_index = np.linalg.inv(theirs.affine)
    n = 0
    for ijk in np.ndindex(*values.shape):
        p_lps_m = affine @ np.array([*ijk, 1.0])
        ras_mm = np.array([-p_lps_m[0] * 1e3, -p_lps_m[1] * 1e3, p_lps_m[2] * 1e3, 1.0])
        index = to_their_index @ ras_mm
        nearest = np.rint(index[:3]).astype(int)
        assert np.abs(index[:3] - nearest).max() < 1e-4, (ijk, index)
        assert values[ijk] == pytest.approx(their_values[tuple(nearest)], abs=1e-9), ijk
        n += 1
    assert n == raw.size
    # Not a copy of the raw ints: the scaling is applied as nibabel applies it.
    assert values.max() == pytest.approx(0.5 * raw.max() - 10.0)


def test_an_array_is_felt_as_the_same_volume_from_a_file(tmp_path):
    """A ball written to NIfTI by nibabel and the same voxels given as an array with the
    affine Scene gives back: the same ticks, force for force; a sheared affine or NaN voxels
    are refused naming the problem."""
    nib = pytest.importorskip("nibabel")
    shape = (40, 40, 40)
    i, j, k = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    ball = (100.0 - np.sqrt((i - 19.5) ** 2 + (j - 19.5) ** 2 + (k - 19.5) ** 2) * 1.0).astype(np.float32)
    A = np.diag([1.0, 1.0, 1.0, 1.0])
    A[:3, 3] = [-19.5, -19.5, -19.5]
    img = nib.Nifti1Image(ball, A)
    img.header.set_xyzt_units("mm")
    path = tmp_path / "ball.nii"
    nib.save(img, str(path))
    tool = {"mesh": "builtin:probe", "point_spacing_m": 0.001}
    from_file = vh.load_scene({"volume": {"path": str(path), "isovalue": 90}, "tool": tool})
    from_array = vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": from_file.affine_LPS_m,
                                           "isovalue": 90}, "tool": tool})
    assert from_array.volume_format == "NumPy array"
    assert np.array_equal(from_array.volume, from_file.volume)
    assert np.array_equal(np.asarray(from_array.affine_LPS_m), np.asarray(from_file.affine_LPS_m))
    # Down onto the ball's top (radius 10 mm at the isovalue 90) and pressed 3 mm in.
    t = np.array([[0.0, 0.0, 0.0, 0.030, 1, 0, 0, 0],
                  [0.5, 0.0, 0.0, 0.007, 1, 0, 0, 0],
                  [1.0, 0.0, 0.0, 0.007, 1, 0, 0, 0]])
    a = vh.run(from_file, t, verify_step_voxels=0, lag_reference=False)
    b = vh.run(from_array, t, verify_step_voxels=0, lag_reference=False)
    assert np.linalg.norm(a.force_N, axis=1).max() > 0.5, "the tool pressed on the ball"
    assert np.array_equal(a.force_N, b.force_N) and np.array_equal(a.proxy_pose, b.proxy_pose)

    sheared = np.asarray(from_file.affine_LPS_m).copy()
    sheared[0, 1] = 0.0005
    with pytest.raises(ValueError, match="not orthogonal"):
        vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": sheared}, "tool": tool})
    holed = from_file.volume.copy()
    holed[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        vh.load_scene({"volume": {"array": holed, "affine_LPS_m": from_file.affine_LPS_m}, "tool": tool})


def test_a_label_array_is_the_segmentation_a_label_file_gives(tmp_path):
    """Segments given as a label array on the volume's grid are the segments a NIfTI label map
    written by nibabel gives: both label the halves of a 12 mm ball by where their voxels are in
    the patient (x < 0: 1, x > 0: 2), both felt (their surface the ball's), and a press on each
    half gives the same ticks from both, the touched segment and the distance to the critical
    one included; the touched half is the one the press is on."""
    nib = pytest.importorskip("nibabel")
    shape = (40, 40, 40)
    i, j, k = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    ball = (100.0 - np.sqrt((i - 19.5) ** 2 + (j - 19.5) ** 2 + (k - 19.5) ** 2)).astype(np.float32)
    A = np.diag([1.0, 1.0, 1.0, 1.0])
    A[:3, 3] = [-19.5, -19.5, -19.5]

    def halves(x_lps_mm, r_mm):
        return np.where(r_mm > 12.0, 0, np.where(x_lps_mm < 0, 1, 2))

    ras = np.einsum("ab,bijk->aijk", A[:3, :3], np.stack([i, j, k])) + A[:3, 3, None, None, None]
    file_labels = halves(-ras[0], np.linalg.norm(ras, axis=0)).astype(np.int16)  # RAS x = -LPS x
    for name, data in (("ball.nii", ball), ("labels.nii", file_labels)):
        img = nib.Nifti1Image(data, A)
        img.header.set_xyzt_units("mm")
        nib.save(img, str(tmp_path / name))
    tool = {"mesh": "builtin:probe", "point_spacing_m": 0.001}
    segmentation = {"felt": ["Label 1", "Label 2"], "critical": ["Label 2"]}  # felt: contacts are named
    from_file = vh.load_scene({"volume": {"path": str(tmp_path / "ball.nii"), "isovalue": 90}, "tool": tool,
                               "segmentation": dict(segmentation, path=str(tmp_path / "labels.nii"))})
    affine = np.asarray(from_file.affine_LPS_m)
    lps_mm = 1000.0 * (np.einsum("ab,bijk->aijk", affine[:3, :3], np.stack([i, j, k])) + affine[:3, 3, None, None, None])
    array_labels = halves(lps_mm[0], np.linalg.norm(lps_mm, axis=0))
    from_array = vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": affine, "isovalue": 90},
                                "tool": tool, "segmentation": dict(segmentation, labels=array_labels)})
    for x_m in (-0.005, 0.005):  # down onto each half of the ball's top, pressed 3 mm in
        t = np.array([[0.0, x_m, 0.0, 0.030, 1, 0, 0, 0],
                      [0.5, x_m, 0.0, 0.006, 1, 0, 0, 0],
                      [1.0, x_m, 0.0, 0.006, 1, 0, 0, 0]])
        a = vh.run(from_file, t, verify_step_voxels=0, lag_reference=False)
        b = vh.run(from_array, t, verify_step_voxels=0, lag_reference=False)
        assert np.linalg.norm(a.force_N, axis=1).max() > 0.5, "the tool pressed on the ball"
        for column in ("force_z_N", "proxy_z_m", "flags", "critical_distance_m", "critical_segment"):
            np.testing.assert_array_equal(a.ticks[column], b.ticks[column], err_msg=column)
        touched = (b.ticks["flags"] >> 16).astype(int) - 1
        expected = 0 if x_m < 0 else 1  # segments in label order: "Label 1", "Label 2"
        assert set(touched[b.ticks["contacts"] > 0]) == {expected}, (x_m, set(touched[b.ticks["contacts"] > 0]))
        pressed = b.ticks["contacts"] > 0
        closest_mm = 1000.0 * b.ticks["critical_distance_m"][pressed].min()
        assert (closest_mm < 0.5) if x_m > 0 else (3.0 < closest_mm < 6.0), (x_m, closest_mm)
    named = vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": affine, "isovalue": 90},
                           "tool": tool, "segmentation": {"felt": [], "critical": ["tumour"], "labels": array_labels,
                                                          "names": {2: "tumour"}}})
    assert named is not None
    with pytest.raises(ValueError, match="shape"):
        vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": affine}, "tool": tool,
                       "segmentation": {"felt": [], "critical": [], "labels": array_labels[:-1]}})
    with pytest.raises(RuntimeError, match="not an integer label"):
        vh.load_scene({"volume": {"array": from_file.volume, "affine_LPS_m": affine}, "tool": tool,
                       "segmentation": {"felt": [], "critical": [], "labels": array_labels + 0.5}})
