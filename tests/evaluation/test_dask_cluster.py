"""``evaluate --cluster``: the model fits on a Dask cluster give the cells of a local run (same splits
and seeds), progress counts the jobs, and bad cluster values are one-line errors."""

from __future__ import annotations

import json
import os
import re

import pytest

from ipromp_pin.evaluation.config import EvaluationConfig
from ipromp_pin.evaluation.dask_cluster import ClusterError, DaskCluster, max_local_workers
from ipromp_pin.evaluation.evaluate import evaluate
from ipromp_pin.evaluation.tables import to_json
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.shipped import DEFAULT_ROBOT

TINY_MODEL = {"n_basis": 9, "n_alpha": 8, "head": False, "handover": False, "coupling": "all", "noise": 3.0}


def test_cluster_values_are_parsed_or_refused() -> None:
    assert DaskCluster.from_spec("dask-local:1") == DaskCluster(n_workers=1)
    assert DaskCluster.from_spec("tcp://10.0.0.5:8786").address == "tcp://10.0.0.5:8786"
    assert DaskCluster.from_spec(" tls://[::1]:8786 ").address == "tls://[::1]:8786"
    bad = {
        "dask-local:0": "number of local workers",
        "dask-local:x": "number of local workers",
        f"dask-local:{max_local_workers() + 1}": "cores and memory",
        "localhost:8786": "neither",
        "tcp://": "host and port",
        "tcp://127.0.0.1": "host and port",
        "tcp://:8786": "host and port",
        "tcp://h:abc": "port must be a number",
        "tcp://h:99999": "port must be a number",
        "inproc://": "neither",
        "ucx://h:1": "neither",
    }
    for spec, problem in bad.items():
        with pytest.raises(ClusterError, match=f"--cluster: '{re.escape(spec)}'.*{problem}"):
            DaskCluster.from_spec(spec)


def test_an_unreachable_scheduler_is_named(monkeypatch) -> None:
    pytest.importorskip("distributed")
    import socket

    from ipromp_pin.evaluation import dask_cluster

    monkeypatch.setattr(dask_cluster, "CONNECT_TIMEOUT_S", 1.0)

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ClusterError, match=f"cannot reach the scheduler at tcp://127.0.0.1:{port}"):
        DaskCluster.from_spec(f"tcp://127.0.0.1:{port}").open()


def test_a_robot_travels_as_its_settings() -> None:
    import pickle

    robot = load_robot(DEFAULT_ROBOT)
    again = pickle.loads(pickle.dumps(robot))
    assert again.settings == robot.settings and again.collision_model is not None


def test_local_cluster_gives_the_cells_of_the_local_run() -> None:
    pytest.importorskip("distributed")
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    cfg = EvaluationConfig(
        protocol="splits", observe=[["orientation"]], grid=[(4, 0.3)], n_test=2, n_splits=3,
        model_params=TINY_MODEL,
    )  # fmt: skip
    local = evaluate(ds, cfg, robot=None, jobs=1)
    seen: list[tuple[int, int]] = []
    cluster = DaskCluster(n_workers=2, processes=False)  # two workers in threads of this process: fast
    remote = evaluate(
        ds, cfg, robot=None, progress=lambda done, total, _: seen.append((done, total)), jobs=cluster
    )
    assert json.dumps(to_json(remote)) == json.dumps(to_json(local))
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_a_worker_that_dies_costs_a_rerun_not_a_cell(tmp_path) -> None:
    pytest.importorskip("distributed")
    from helpers_dask import DyingRunner

    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    cfg = EvaluationConfig(
        protocol="splits", observe=[["orientation"]], grid=[(4, 0.3)], n_test=2, n_splits=3,
        model_params=TINY_MODEL,
    )  # fmt: skip
    local = evaluate(ds, cfg, robot=None, jobs=1)
    marker = tmp_path / "killed"
    seen: list[tuple[int, int]] = []
    runner = DyingRunner(DaskCluster(n_workers=2), marker, index=1)  # worker processes: one is killed
    remote = evaluate(
        ds, cfg, robot=None, progress=lambda done, total, _: seen.append((done, total)), jobs=runner
    )
    assert marker.exists() and int(marker.read_text()) != os.getpid()  # a worker process died ...
    assert json.dumps(to_json(remote)) == json.dumps(to_json(local))  # ... and its job was run again
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_a_bad_cluster_is_a_one_line_error_before_any_demo_is_read(tmp_path, capsys) -> None:
    from ipromp_pin.app import main

    assert main(["evaluate", str(tmp_path), "--cluster", "localhost:8786"]) == 2
    err = capsys.readouterr().err
    assert "--cluster: 'localhost:8786' is neither" in err and len(err.strip().splitlines()) == 1


def test_a_scheduler_address_runs_both_protocols_of_the_closed_loop_with_the_baselines(tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    pytest.importorskip("sklearn")
    from test_protocol import _write_dataset

    from ipromp_pin.evaluation.run import EvaluateRequest, grid_from, run_evaluate

    data = _write_dataset(tmp_path / "data")
    seen: list[tuple[int, int]] = []

    def request(out, cluster=None):
        return EvaluateRequest(
            dataset=data, observe=[["orientation", "emg"]], grid=grid_from("full", [4], [0.2]),
            protocols=["paper", "splits"], n_test=1, n_splits=1, baselines=True, closed_loop=True,
            cluster=cluster, json=out, log=lambda line: None,
            progress=lambda: lambda done, total, _: seen.append((done, total)),
        )  # fmt: skip

    run_evaluate(request(tmp_path / "local.json"))
    local = json.loads((tmp_path / "local.json").read_text())["cells"]
    seen.clear()
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None, protocol="tcp"
    ) as scheduler:  # an existing scheduler, its worker a thread of this process (one: the robot is shared)
        run_evaluate(request(tmp_path / "remote.json", cluster=scheduler.scheduler_address))
    remote = json.loads((tmp_path / "remote.json").read_text())["cells"]
    assert len(local) == 4 and json.dumps(remote) == json.dumps(local)
    assert {c["protocol"] for c in remote} == {"paper", "splits"}
    assert seen[-2:] == [(1, 1), (1, 1)]  # jobs done / total, per protocol (after the reading)


def test_the_cluster_says_that_it_started_and_how_many_workers_it_has() -> None:
    distributed = pytest.importorskip("distributed")
    lines: list[str] = []
    with DaskCluster.from_spec("dask-local:2", log=lines.append).open():
        pass
    with DaskCluster(n_workers=2, processes=False, log=lines.append).open():
        pass
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None, protocol="tcp"
    ) as sch:
        with DaskCluster.from_spec(sch.scheduler_address, log=lines.append).open():
            pass
    assert lines[0].startswith("[cluster] started a local Dask cluster at tcp://127.0.0.1:")
    assert lines[0].endswith("(processes): 2 workers, 2 threads")
    assert lines[1].endswith("(threads of this process): 2 workers, 2 threads")
    assert (
        lines[2]
        == f"[cluster] connected to the Dask scheduler at {sch.scheduler_address}: 1 worker, 1 thread"
    )
