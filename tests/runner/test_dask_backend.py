"""``--scheduler``: the same matrix on a Dask distributed LocalCluster (2 worker processes).

Each cell runs in a child interpreter of a Dask worker, so an engine segfault or hang costs that
cell only; a shared fine-step reference is computed once, before the cells that need it.
"""

from __future__ import annotations

import pytest
from crosscheck_fakes import ALL
from test_runner_matrix import G, by_id, write_case

from crosscheck.runner.plan import build_matrix
from crosscheck.runner.session import run_and_report
from crosscheck.scene.loader import load_case

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, memory_limit="2GiB") as c:
        yield c


@pytest.mark.slow
def test_matrix_on_a_local_dask_cluster(tmp_path, cluster):
    from crosscheck.runner.dask_backend import DaskBackend

    case = write_case(tmp_path, "dask", engines='["inhouse", "mujoco", "pybullet"]',
                      integrators='{ inhouse = ["exact", "euler"], mujoco = ["exact"], '
                                  'pybullet = ["exact"] }', timeout=4)
    er = {"inhouse": ALL["exact"], "mujoco": ALL["crash"], "pybullet": ALL["hang"]}
    # The fakes' integrator names ("exact") are accepted for the engines they replace.
    matrix = build_matrix([load_case(case, unchecked_engines=er)], out=tmp_path / "out",
                          engine_refs=er)
    backend = DaskBackend(cluster.scheduler_address)
    assert backend.workers == 2
    outcome = run_and_report(matrix, backend, tmp_path / "out")
    cells = by_id(outcome)
    euler = cells["dask::inhouse-euler@dt=0.01"]
    assert euler["status"] == "pass"
    assert euler["metrics"]["position_error_max"]["value"] == pytest.approx(G * 0.01 / 2, 1e-9)
    assert cells["dask::inhouse-exact@dt=0.01"]["status"] == "pass"
    crash = cells["dask::mujoco-exact@dt=0.01"]
    assert crash["status"] == "error" and "SIGSEGV" in crash["reason"]
    hang = cells["dask::pybullet-exact@dt=0.01"]
    assert hang["status"] == "timeout"
    assert outcome.doc["references"][0]["status"] == "ok"
    assert outcome.doc["resources"]["backend"] == "dask"
    # The cluster survived: both workers are still there for the next user.
    with distributed.Client(cluster.scheduler_address) as client:
        assert len(client.scheduler_info()["workers"]) == 2
