"""ik5r sweep on Dask: a worker killed mid-sweep loses no point, and a real scheduler with two
workers on 127.0.0.1 gives the local run's figures bit for bit."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ik5r.tools.cli import main
from ik5r.tools.sweep_record import SweepRecord

#: Figures that depend on the run, not on the point.
RUN_FIELDS = ("error_seconds", "error_cpu_seconds", "error_from_cache", "synth_from_cache")


def _figures(out: Path) -> list[dict]:
    points = SweepRecord.read(out).points
    return [{k: v for k, v in p.items() if k not in RUN_FIELDS} for p in points]


def test_worker_killed_mid_sweep_loses_no_point(tmp_path):
    from dask.distributed import Client, LocalCluster

    from ik5r.tools.sweep import run_sweep
    from ik5r.tools.sweep_record import SweepOptions

    widths = list(range(12, 20))
    killed = {}

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=50) as cluster, Client(cluster) as client:
        pids = client.run(os.getpid)

        def kill_a_busy_worker(task, doc):
            if killed:
                return
            for address, keys in client.processing().items():
                if keys and address in pids:
                    killed.update(address=address, keys=list(keys))
                    os.kill(pids[address], signal.SIGKILL)
                    return

        result = run_sweep(SweepOptions(widths=widths, blocks=(), archs=(), poses=40_000, synth=False),
                           out_dir=tmp_path / "sweep", client=client, progress=False, log=lambda m: None,
                           on_done=kill_a_busy_worker)
        assert killed, "no worker was busy when the first point came back"
        # The nanny restarted the killed worker under a new process id.
        client.wait_for_workers(2, timeout=30)
        assert set(client.run(os.getpid).values()) != set(pids.values())

    points = result.points
    assert [p["name"] for p in points] == [f"w{w}" for w in widths]          # each once, in order
    assert result.failures == [] and result.meta["tasks_run"] == len(widths)
    for p in points:
        assert p["position_err_max_cm"] >= p["position_err_rms_cm"] > 0 and p["poses"] == 40_000
    assert len(list((tmp_path / "sweep" / "cache").glob("error_*.json"))) == len(widths)
    # Every point the killed worker held came back, with the figures of an undisturbed run.
    again = run_sweep(SweepOptions(widths=widths[:2], blocks=(), archs=(), poses=40_000, synth=False),
                      out_dir=tmp_path / "calm", jobs=1, progress=False, log=lambda m: None)
    assert [{k: v for k, v in p.items() if k not in RUN_FIELDS} for p in again.points] == \
        [{k: v for k, v in p.items() if k not in RUN_FIELDS} for p in points[:2]]


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _dask_command() -> list[str]:
    script = Path(sys.executable).with_name("dask")
    if script.exists():
        return [str(script)]
    found = shutil.which("dask")
    if not found:
        pytest.skip("the dask command line is not installed")
    return [found]


def test_scheduler_and_two_workers_match_local_run(tmp_path):
    from dask.distributed import Client

    address = f"tcp://127.0.0.1:{_free_port()}"
    dask = _dask_command()
    logs = open(tmp_path / "dask.log", "w")
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                               "--no-dashboard"], stdout=logs, stderr=logs, cwd=tmp_path)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--no-dashboard",
                                           "--local-directory", str(tmp_path / "workers")],
                                          stdout=logs, stderr=logs, cwd=tmp_path))
        deadline = time.monotonic() + 60
        while True:
            try:
                with Client(address, timeout="5s") as client:
                    client.wait_for_workers(2, timeout=max(1, deadline - time.monotonic()))
                    worker_pids = set(client.run(os.getpid).values())
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        assert len(worker_pids) == 2 and os.getpid() not in worker_pids
        axes = ["--no-synth", "--widths", "12,20", "--guard-bits", "0,3", "--poses", "5000", "-q"]
        assert main(["sweep", *axes, "--scheduler", address, "-o", str(tmp_path / "cluster")]) == 0
        meta = SweepRecord.read(tmp_path / "cluster").meta
        assert meta["cluster"] == address and meta["tasks_run"] == 4
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
        logs.close()
    assert main(["sweep", *axes, "--jobs", "2", "-o", str(tmp_path / "local")]) == 0
    cluster, local = _figures(tmp_path / "cluster"), _figures(tmp_path / "local")
    assert [p["name"] for p in cluster] == ["w12g0", "w12g3", "w20g0", "w20g3"]
    assert json.dumps(cluster, sort_keys=True) == json.dumps(local, sort_keys=True)
    assert (tmp_path / "cluster" / "sweep.csv").read_text() != ""
