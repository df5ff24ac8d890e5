"""volume_haptics.study on a Dask cluster (Debian python3-distributed): a LocalCluster of two
worker processes gives the plain loop's table, row for row; a failed run's error reaches the
caller with its message. The oracle is the plain loop, which test_volume_haptics.py checks
against the command line."""
import pathlib

import numpy as np
import pytest

import volume_haptics as vh
import volume_haptics.study as st
from vh_test_support import SOURCE, cli

pd = pytest.importorskip("pandas", reason="python3-pandas is not installed (packaging/setup.sh test installs it)")
distributed = pytest.importorskip("distributed",
                                  reason="python3-distributed is not installed (packaging/setup.sh test installs it)")

SCENE = SOURCE / "resources/scenes/sphere-probe.json"


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """Six runs: two trajectories (a push-and-slide from make-trajectory sped up 5 times, and a
    deeper push) x three coupling stiffnesses on the sphere."""
    d = tmp_path_factory.mktemp("study")
    cli("make-trajectory", "--scene", SCENE, "--out", d / "slow.csv")
    push = vh.read_trajectory(d / "slow.csv")
    push[:, 0] *= 0.2
    deeper = push.copy()
    deeper[:, 3] -= 0.002  # 2 mm lower all along
    runs = st.parameter_study({"sphere": SCENE}, {"push": push, "deeper": deeper},
                              [{"coupling": {"linear_N_per_m": k}} for k in (300, 1000, 3000)])
    return d, runs


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    from distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                           local_directory=str(tmp_path_factory.mktemp("dask")))
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_a_two_worker_cluster_gives_the_plain_loops_table(study, client):
    d, runs = study
    assert len(runs) == 6
    plain = st.run_study(runs)
    on_cluster = st.run_study(runs, client=client)
    pd.testing.assert_frame_equal(plain, on_cluster)
    assert list(plain["coupling.linear_N_per_m"]) == [300, 1000, 3000] * 2
    assert list(plain["trajectory"]) == ["push"] * 3 + ["deeper"] * 3
    # The table says something: every run touched, and the force grew with the stiffness.
    assert (plain["ticks_in_contact"] > 0).all() and (plain["crossings"] == 0).all()
    for name in ("push", "deeper"):
        forces = plain[plain["trajectory"] == name]["max_force_N"].to_numpy()
        assert np.all(np.diff(forces) > 0), forces


def test_cohort_on_the_cluster_is_the_plain_cohort(study, client):
    d, runs = study
    table = st.run_study(runs[:4], client=client, record_dir=str(d / "rec"))
    paths = list(table["recording"])
    assert all(pathlib.Path(p).exists() for p in paths)
    plain = st.cohort(paths)
    pd.testing.assert_frame_equal(plain, st.cohort(paths, client=client))
    assert list(plain["file"]) == paths


def test_a_failed_run_reaches_the_caller_with_its_message(study, client):
    d, runs = study
    bad = dict(runs[0], scene={"volume": {"path": str(d / "missing.nrrd")}, "tool": {"mesh": "builtin:probe"}})
    with pytest.raises(Exception, match="missing.nrrd"):
        st.run_study([runs[0], bad], client=client)
