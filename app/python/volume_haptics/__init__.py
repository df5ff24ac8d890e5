"""VolumeHaptics from Python: headless runs, recordings, trajectories and session metrics.

The functions call the same C++ code as the command line (``volume-haptics run``, ``export``,
``report``), so a study scripted here gets the same ticks, numbers and error messages:

    import numpy as np, volume_haptics as vh
    scene = vh.load_scene("resources/scenes/sphere-probe.json")
    result = vh.run(scene, trajectory)            # trajectory: (N, 8) array, see run()
    result.force_N.max(), result.report["max_penetration_m"]

Frames and units everywhere: W is the scene (world) frame (patient LPS for scans), positions in
metres, quaternions (w, x, y, z) of the rotation R_WD (device) or R_WP (proxy), forces in newtons
(on the user's hand, in W), torques in newton metres, times in seconds.

Errors are Python exceptions carrying the command line's message (what ``volume-haptics`` prints
after "volume-haptics: error: "): ``LoadError`` (a ``RuntimeError``) for a volume, segmentation or
mesh that cannot be read, ``RuntimeError`` for a bad scene, trajectory or recording file,
``ValueError`` for bad arguments (a trajectory of the wrong shape, times not increasing).
"""
import json
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Union

import numpy as np

from . import _core
from ._core import LoadError

__all__ = [
    "LoadError", "Scene", "RunResult", "Recording", "TICK_DTYPE", "load_scene", "run", "read_recording",
    "write_trajectory", "read_trajectory", "session_metrics",
]

#: One servo tick of a recording, as NumPy sees the file's TickRecord (recording.h), its fields in
#: the record's order. Their names are the columns of ``volume-haptics export --csv``; each one's
#: unit and meaning are in ``_core.TICK_COLUMNS`` (name, unit, description, byte offset, NumPy
#: type), the table the CSV and HDF5 exports are written from: device_* and proxy_* are the device
#: and proxy poses in W (position [m], quaternion w, x, y, z), force_* [N] and torque_* [N*m] on the
#: hand in W, flags the kRecordFlag* bits (bits 16..31: touched segment + 1).
_BY_OFFSET = sorted(_core.TICK_COLUMNS, key=lambda c: c[3])
TICK_DTYPE = np.dtype({
    "names": [c[0] for c in _BY_OFFSET],
    "formats": [c[4] for c in _BY_OFFSET],
    "offsets": [c[3] for c in _BY_OFFSET],
    "itemsize": _core.TICK_RECORD_BYTES,
})

#: The columns of ``volume-haptics export --csv``, in its order.
CSV_COLUMNS = [c[0] for c in _core.TICK_COLUMNS]

Scene = _core.Scene
# Scene's docstring: volume_haptics_core.cpp.


def _ticks(raw: np.ndarray) -> np.ndarray:
    return np.frombuffer(raw.tobytes(), dtype=TICK_DTYPE)


def load_scene(scene: Union[str, "os.PathLike[str]", Dict[str, Any]], base_dir: Union[str, "os.PathLike[str]", None] = None) -> Scene:
    """Loads a scene: a scene .json file, or a dict with the file's keys (volume, tool, coupling,
    segmentation, drill; see docs/command-line.md, "Scene files"). The dict's volume may be an
    array instead of a file: {"array": a, "affine_LPS_m": A, "isovalue": s}, `a` (nx, ny, nz)
    indexed [i, j, k] in data units, `A` the 4 x 4 index -> patient LPS [m] (voxel centres at
    integer indices; Scene.volume and Scene.affine_LPS_m give them back). Raises ValueError for
    an array or affine it cannot place (shape, NaN, shear, voxels below 1 um).

    base_dir: where a dict's relative paths resolve first (default: the current folder), then the
    shared datasets and the generated data, as for a scene file's folder.
    Returns a Scene. Raises LoadError (volume / mesh unreadable) or RuntimeError (bad scene) with
    the command line's message; the source is the file name, or "scene dict" for a dict.
    """
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, dict):
        volume = scene.get("volume")
        if isinstance(volume, dict) and "array" in volume:
            # A volume made in Python: {"array": (nx, ny, nz) values indexed [i, j, k],
            # "affine_LPS_m": 4 x 4 index -> patient LPS [m], voxel centres at integer indices},
            # felt as it is (no file written). The rest of the scene as from a file.
            rest = {k: v for k, v in volume.items() if k not in ("array", "affine_LPS_m")}
            if "affine_LPS_m" not in volume:
                raise ValueError("volume: an array needs its affine_LPS_m (4 x 4, index -> patient LPS [m])")
            # The scene text names a built-in volume in the array's place (a path the parser takes
            # without a file); load_scene_array() replaces it with the array.
            spec = dict(scene, volume=dict(rest, path="builtin:plane"))
            # Segments as a label array on the volume's grid: {"labels": (nx, ny, nz) integers
            # (0: none), "names": {label: name}, "felt": [...], "critical": [...], ...}.
            labels, names = None, {}
            segmentation = scene.get("segmentation")
            if isinstance(segmentation, dict) and "labels" in segmentation:
                labels = np.asarray(segmentation["labels"], dtype=np.float64)
                names = {int(k): str(v) for k, v in segmentation.get("names", {}).items()}
                spec["segmentation"] = dict({k: v for k, v in segmentation.items() if k not in ("labels", "names")},
                                            path="builtin:plane")
            return _core.load_scene_array(json.dumps(spec), "scene dict", os.fspath(base_dir or os.getcwd()),
                                          np.asarray(volume["array"], dtype=np.float64),
                                          np.asarray(volume["affine_LPS_m"], dtype=np.float64), labels, names)
        return _core.load_scene_json(json.dumps(scene), "scene dict", os.fspath(base_dir or os.getcwd()))
    return _core.load_scene_file(os.fspath(scene))


@dataclass
class RunResult:
    """What run() returns: one row per servo tick (N ticks), and the run's report.

    ticks: structured array (N,) of TICK_DTYPE (the columns of ``export --csv``).
    t_s: (N,) servo time of each tick [s], from 0.
    device_pose, proxy_pose: (N, 7) position in W [m] and quaternion (w, x, y, z) of R_WD / R_WP.
    force_N: (N, 3) force on the hand in W [N] (the renderer's, before the safety layer).
    torque_Nm: (N, 3) torque on the hand in W [N*m].
    contacts: (N,) contact set size per tick.
    report: the run report as a dict (the keys of ``run --report``'s JSON: ticks, mean_us, max_force_N,
    max_penetration_m, crossings, ...).
    """
    ticks: np.ndarray
    report: Dict[str, Any]
    t_s: np.ndarray = field(init=False)
    device_pose: np.ndarray = field(init=False)
    proxy_pose: np.ndarray = field(init=False)
    force_N: np.ndarray = field(init=False)
    torque_Nm: np.ndarray = field(init=False)
    contacts: np.ndarray = field(init=False)

    def __post_init__(self):
        t = self.ticks

        def cols(*names):
            return np.column_stack([t[n] for n in names]) if len(t) else np.zeros((0, len(names)))

        self.t_s = np.array(t["t_s"])
        self.device_pose = cols("device_x_m", "device_y_m", "device_z_m", "device_qw", "device_qx", "device_qy",
                                "device_qz")
        self.proxy_pose = cols("proxy_x_m", "proxy_y_m", "proxy_z_m", "proxy_qw", "proxy_qx", "proxy_qy", "proxy_qz")
        self.force_N = cols("force_x_N", "force_y_N", "force_z_N")
        self.torque_Nm = cols("torque_x_Nm", "torque_y_Nm", "torque_z_Nm")
        self.contacts = np.array(t["contacts"])


def _trajectory_array(trajectory) -> np.ndarray:
    a = np.ascontiguousarray(trajectory, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] not in (8, 9):
        raise ValueError("trajectory: expected an (N, 8) or (N, 9) array (t_s, x_m, y_m, z_m, qw, qx, qy, qz[, "
                         "isovalue]), got shape %s" % (a.shape,))
    return a


def run(scene, trajectory, *, servo_rate_Hz: float = 1000.0, verify_step_voxels: float = 0.01,
        lag_reference: bool = True, record: Union[str, "os.PathLike[str]", None] = None) -> RunResult:
    """Replays a device trajectory through the renderer, as ``volume-haptics run`` does.

    scene: a Scene (load_scene(); load once, run many), a scene dict or a scene file.
    trajectory: (N, 8) or (N, 9) array of key poses of the device in W, one row per key:
        t_s [s, strictly increasing], x_m, y_m, z_m [m], qw, qx, qy, qz (R_WD, normalised on use)
        [, isovalue in data units, NaN for the scene's]; or a trajectory CSV file.
        Tick i runs at t = t_first + i / servo_rate_Hz up to the last key's time.
    servo_rate_Hz: the simulated servo rate [Hz]. verify_step_voxels: the crossing check's step
    [voxels], 0 turns it off. lag_reference: also measure the work budget's lag.
    record: also keep the session recording (.vhrec) here (``run --record``).
    The GIL is released while the renderer runs, so runs in threads proceed in parallel.
    Returns a RunResult (per-tick NumPy arrays and the report dict).
    Raises LoadError / RuntimeError / ValueError with the command line's messages.
    """
    loaded = load_scene(scene)
    if isinstance(trajectory, (str, os.PathLike)):
        name = os.fspath(trajectory)
        trajectory = _core.read_trajectory(name)
    else:
        name = "python"
        trajectory = _trajectory_array(trajectory)
    with tempfile.TemporaryDirectory(prefix="volume-haptics-") as tmp:
        path = os.fspath(record) if record is not None else os.path.join(tmp, "run.vhrec")
        report_json, rec = _core.run(loaded, trajectory, path, float(servo_rate_Hz), float(verify_step_voxels),
                                     bool(lag_reference), name)
    return RunResult(ticks=_ticks(rec[2]), report=json.loads(report_json))


@dataclass
class Recording:
    """A session recording (.vhrec, or its HDF5 export) as read back (``volume-haptics export``).

    ticks: structured array (N,) of TICK_DTYPE, one per servo tick (the ``export --csv`` rows).
    events: list of dicts {"t_s", "tick", "type", "detail"} (detail: the event's JSON object).
    metadata: the header's JSON object (scene, dataset and its SHA-256, tool, gains, device, ...).
    scene: metadata["scene"], the scene description (or None).
    warnings: a truncated or damaged tail, one sentence each (empty for a clean file).
    version, chunks, dropped_records, bytes_ignored: as ``export`` reports them; event_chunks,
    damaged_regions, ended (the writer closed the file) and end_status (0, or the errno of the
    write failure that ended it): the rest of what the reader found.
    """
    ticks: np.ndarray
    events: List[Dict[str, Any]]
    metadata: Dict[str, Any]
    warnings: List[str]
    version: int
    chunks: int
    dropped_records: int
    bytes_ignored: int
    event_chunks: int = 0
    damaged_regions: int = 0
    ended: bool = False
    end_status: int = 0

    @property
    def scene(self) -> Optional[Dict[str, Any]]:
        return self.metadata.get("scene")

    def dataframe(self):
        """The ticks as a pandas DataFrame, columns in ``export --csv``'s order.
        Raises ImportError when pandas is not installed."""
        import pandas as pd
        return pd.DataFrame({c: self.ticks[c] for c in CSV_COLUMNS})

    def drilled_volume(self):
        """The drilled field at the recording's end, as a replay of it carves the scan: float64
        (nx, ny, nz) indexed [i, j, k] in data units (removed voxels at the scan's lowest value),
        and its affine_LPS_m (4 x 4), as Scene.volume and Scene.affine_LPS_m. Needs the
        recording's dataset, unchanged, where its metadata says; takes a replay's time.
        Returns (array, affine). Raises RuntimeError when the recorded scene has no drill, the
        dataset is missing or changed, or the replay parts from the recording (saying where)."""
        return _core.drilled_volume(self._fields())

    def _fields(self):
        events = [(float(e["t_s"]), int(e["tick"]), str(e["type"]), json.dumps(e["detail"]) if e["detail"] else "")
                  for e in self.events]
        return (int(self.version), json.dumps(self.metadata) if self.metadata else "",
                np.ascontiguousarray(self.ticks, dtype=TICK_DTYPE).tobytes(), events, list(self.warnings),
                int(self.chunks), int(self.dropped_records), int(self.bytes_ignored), int(self.event_chunks),
                int(self.damaged_regions), bool(self.ended), int(self.end_status))

    def to_hdf5(self, path: Union[str, "os.PathLike[str]"], *, volume: bool = False) -> str:
        """Writes this recording as one HDF5 file (``export --hdf5``; layout in docs/python.md):
        /ticks/<column> one dataset per TICK_DTYPE field (unit and description attributes),
        /events, /markers, /metadata and /scene (JSON text), /warnings. read_recording() of the
        file gives this recording back, field for field.

        volume: also /volume/scan, the scan as felt with its affine_LPS_m, and with a drill
        /volume/drilled, the field a replay carved by the end (``export --hdf5-volume``); needs
        the recording's dataset, unchanged, where its metadata says.
        Returns "" or, when the replay parted from the recording, why (the drilled field is then
        left out). Raises RuntimeError (a target that is not a regular file, a full disk, the
        dataset missing or changed), ValueError for ticks that are not whole records."""
        return _core.write_recording_hdf5(self._fields(), os.fspath(path), bool(volume))


def _recording(fields) -> Recording:
    version, metadata, raw, events, warnings, chunks, dropped, ignored, event_chunks, damaged, ended, status = fields
    return Recording(
        ticks=_ticks(raw),
        events=[{"t_s": t, "tick": k, "type": ty, "detail": json.loads(d) if d else {}} for t, k, ty, d in events],
        metadata=json.loads(metadata) if metadata else {}, warnings=list(warnings), version=version, chunks=chunks,
        dropped_records=dropped, bytes_ignored=ignored, event_chunks=event_chunks, damaged_regions=damaged,
        ended=ended, end_status=status)


def read_recording(path: Union[str, "os.PathLike[str]"]) -> Recording:
    """Reads a session recording (.vhrec up to its last good chunk, or an HDF5 file written by
    ``export --hdf5`` / Recording.to_hdf5(), recognised by its signature; see Recording).
    Raises RuntimeError (not a recording, unsupported version, damaged header) with the
    command line's message."""
    return _recording(_core.read_recording(os.fspath(path)))


def write_trajectory(path: Union[str, "os.PathLike[str]"], trajectory) -> None:
    """Writes an (N, 8) or (N, 9) trajectory array (see run()) as the CSV ``run --trajectory``
    reads (header line, 17 significant digits: it reads back bit for bit; quaternions normalised).
    Raises ValueError for a bad array (shape, times not increasing, a zero quaternion),
    RuntimeError when the file cannot be written."""
    _core.write_trajectory(os.fspath(path), _trajectory_array(trajectory))


def read_trajectory(path: Union[str, "os.PathLike[str]"]) -> np.ndarray:
    """Reads a trajectory CSV into an (N, 8) array, (N, 9) when a key requests an isovalue (NaN
    where one does not). Raises RuntimeError naming the file and line for a bad CSV."""
    return _core.read_trajectory(os.fspath(path))


def session_metrics(recording: Union[str, "os.PathLike[str]"], *, force_threshold_N: float = 2.0,
                    derivative_step_s: float = 0.01) -> Dict[str, Any]:
    """The session metrics of a recording, as ``volume-haptics report --table`` writes them: a flat
    dict of file, scene, dataset_sha256, label, start_time_utc, then every metric keyed with its
    unit (path_length_m, mean_force_N, time_in_contact_s, log_dimensionless_jerk, ...), then
    "segments" (a list of dicts per segment) and "notices". A cohort is a list comprehension:
    ``pandas.DataFrame([vh.session_metrics(p) for p in paths])``.

    force_threshold_N: |F| above which time is counted [N]; derivative_step_s: the central
    differences' step for speed and jerk [s]. Raises RuntimeError for an unreadable recording,
    ValueError for out-of-range options."""
    path = os.fspath(recording)
    identity, values, segments, notices = _core.session_metrics(path, float(force_threshold_N),
                                                               float(derivative_step_s))
    out: Dict[str, Any] = {"file": path}
    out.update(identity)
    for key, _label, _unit, value in values:
        out[key] = value
    out["segments"] = segments
    out["notices"] = list(notices)
    return out
