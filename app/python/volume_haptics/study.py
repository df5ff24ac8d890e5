"""Studies at scale: a parameter study (scenes x trajectories x parameters) and a cohort of
recordings, as one pandas table, run in a plain loop or on a Dask cluster with the same code.

    import volume_haptics.study as st
    runs = st.parameter_study({"sphere": "resources/scenes/sphere-probe.json"},
                              {"push": trajectory_array},
                              [{"coupling": {"linear_N_per_m": k}} for k in (250, 500, 1000)])
    table = st.run_study(runs)                        # a plain loop, this process
    from dask.distributed import Client
    table = st.run_study(runs, client=Client("tcp://scheduler:8786"))   # a cluster
    cohort = st.cohort(paths, client=client)          # session_metrics of each recording

A run is a plain dict (picklable: scene as a file path or a scene dict, the trajectory as an
array or a CSV path, the parameters as a dict merged into the scene), so it travels to workers
as it is. Each worker keeps the scenes it has loaded (keyed by the merged scene's JSON), so a
volume is read once per worker and parameter set, not once per run; the trajectory travels with
each run (a few kB). Every row is computed by the same code whatever ran it, and the rows come
back in the order of the runs, so a cluster gives the plain loop's table.

Row columns: scene, trajectory, the parameters flattened ("coupling.linear_N_per_m"), then per
run the report's deterministic results (ticks, ticks_in_contact, max_contacts, max_force_N,
max_torque_Nm, max_penetration_m, crossings, edge_crossings, budget_cuts, jams, final_force_N,
max_proxy_device_distance_m) and from the ticks mean_contact_force_N (mean |F| over ticks in
contact) and path_length_m (the device's). Timing (mean_us, ...) is left out: it measures the
machine, not the run. Pass record_dir to keep each run's recording (named by its index).
"""
import copy
import json
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np

from . import load_scene, read_trajectory, run, session_metrics

__all__ = ["parameter_study", "run_one", "run_study", "cohort", "REPORT_COLUMNS"]

#: The run report's keys a study row keeps (deterministic: the same on any machine).
REPORT_COLUMNS = ["ticks", "ticks_in_contact", "max_contacts", "max_force_N", "max_torque_Nm", "max_penetration_m",
                  "crossings", "edge_crossings", "budget_cuts", "jams", "final_force_N",
                  "max_proxy_device_distance_m"]

# Scenes loaded in this process (a worker's cache), keyed by (merged scene JSON, base folder).
_scene_cache: Dict[Any, Any] = {}


def _merged(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> Dict[str, Any]:
    """`base` with `overrides` merged in, dicts key by key (a copy; neither is changed)."""
    out = copy.deepcopy(dict(base))
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merged(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _flat(prefix: str, value: Any, out: Dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flat(prefix + "." + k if prefix else k, v, out)
    else:
        out[prefix] = value


def parameter_study(scenes: Mapping[str, Union[str, "os.PathLike[str]", Mapping[str, Any]]],
                    trajectories: Mapping[str, Any],
                    parameters: Sequence[Mapping[str, Any]] = ({},)) -> List[Dict[str, Any]]:
    """Every combination of a scene, a trajectory and a parameter set, as run dicts for
    run_study() (scenes outermost, parameters innermost).

    scenes: name -> scene file path or scene dict (a dict's relative paths are taken from the
    current folder, as load_scene()'s). trajectories: name -> (N, 8) or (N, 9) array or CSV path
    (see volume_haptics.run). parameters: dicts merged into each scene's keys, e.g.
    {"coupling": {"linear_N_per_m": 500}}. Raises ValueError when a scene, trajectory or
    parameter list is empty."""
    if not scenes or not trajectories or not parameters:
        raise ValueError("parameter_study: needs at least one scene, one trajectory and one parameter set")
    runs = []
    for scene_name, scene in scenes.items():
        for trajectory_name, trajectory in trajectories.items():
            if not isinstance(trajectory, (str, os.PathLike)):
                trajectory = np.asarray(trajectory, dtype=np.float64)
            for params in parameters:
                runs.append({"scene_name": scene_name,
                             "scene": os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else dict(scene),
                             "trajectory_name": trajectory_name,
                             "trajectory": os.fspath(trajectory) if isinstance(trajectory, (str, os.PathLike))
                             else trajectory,
                             "parameters": dict(params)})
    return runs


def _loaded(scene: Union[str, Mapping[str, Any]], parameters: Mapping[str, Any]):
    """The scene with the parameters merged in, loaded once in this process."""
    if isinstance(scene, str):
        base_dir = os.path.dirname(os.path.abspath(scene))
        with open(scene) as f:
            spec = json.load(f)
    else:
        base_dir, spec = os.getcwd(), dict(scene)
    spec = _merged(spec, parameters)
    key = (json.dumps(spec, sort_keys=True, default=str), base_dir)
    if key not in _scene_cache:
        _scene_cache[key] = load_scene(spec, base_dir=base_dir)
    return _scene_cache[key]


def run_one(one: Mapping[str, Any], record_dir: Optional[str] = None, index: int = 0) -> Dict[str, Any]:
    """One run of a parameter_study() list as a table row (see the module's docstring). With
    record_dir, its recording is kept there as run-INDEX.vhrec. Raises what load_scene() and
    run() raise."""
    scene = _loaded(one["scene"], one["parameters"])
    trajectory = one["trajectory"]
    if isinstance(trajectory, str):
        trajectory = read_trajectory(trajectory)
    record = os.path.join(record_dir, "run-%05d.vhrec" % index) if record_dir else None
    result = run(scene, trajectory, lag_reference=False, record=record)
    row: Dict[str, Any] = {"scene": one["scene_name"], "trajectory": one["trajectory_name"]}
    _flat("", one["parameters"], row)
    for key in REPORT_COLUMNS:
        row[key] = result.report[key]
    force = np.linalg.norm(result.force_N, axis=1)
    touching = result.contacts > 0
    row["mean_contact_force_N"] = float(force[touching].mean()) if touching.any() else 0.0
    row["path_length_m"] = float(np.linalg.norm(np.diff(result.device_pose[:, :3], axis=0), axis=1).sum())
    if record:
        row["recording"] = record
    return row


def _table(rows: Iterable[Dict[str, Any]]):
    import pandas as pd
    return pd.DataFrame(list(rows))


def run_study(runs: Sequence[Mapping[str, Any]], client=None, record_dir: Optional[str] = None):
    """Runs every run of `runs` and returns one pandas DataFrame, a row per run in their order.

    client: None runs them here, one after the other; a dask.distributed Client runs them on its
    cluster (client.map, one task per run; pure=False so none is skipped as a duplicate). The
    table is the same either way. record_dir: keep each run's recording there (a folder every
    worker can write: a shared file system on a real cluster). Raises ImportError without pandas,
    and the first failed run's exception."""
    if record_dir:
        os.makedirs(record_dir, exist_ok=True)
    if client is None:
        return _table(run_one(one, record_dir, i) for i, one in enumerate(runs))
    futures = client.map(run_one, list(runs), [record_dir] * len(runs), list(range(len(runs))), pure=False)
    return _table(client.gather(futures))


def _metrics_row(path: str) -> Dict[str, Any]:
    m = session_metrics(path)
    m.pop("segments", None)
    m["notices"] = "; ".join(m["notices"])
    return m


def cohort(paths: Iterable[Union[str, "os.PathLike[str]"]], client=None):
    """session_metrics() of each recording (.vhrec or its HDF5 export) as one pandas DataFrame,
    a row per recording in the order given (the columns of ``report --table``, the per-segment
    figures left out, the notices joined by "; "). client: as run_study(); each worker reads the
    recordings it is given by path, so they must be where every worker can read them."""
    paths = [os.fspath(p) for p in paths]
    if client is None:
        return _table(_metrics_row(p) for p in paths)
    return _table(client.gather(client.map(_metrics_row, paths, pure=False)))
