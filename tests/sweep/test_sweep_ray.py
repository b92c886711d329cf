"""``hilrig sweep --engine ray`` on a real two-node Ray cluster started on this machine: the same
metrics as the local engine, tasks on both nodes, and a node killed mid-sweep without losing a
result. Each node is ``ray start --block`` in a session of its own, and killing a node kills
every process of its session: Ray puts each worker in a process group of its own, so a worker
outlives a signal to the node's group (and may finish a task after its node was "killed"). A
watchdog kills the nodes if the module hangs.
Token authentication is off (``RAY_AUTH_MODE=disabled``): the nodes listen on loopback only."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import pytest
from sweep_helpers import SWEEP, force_table, hilrig, sessions

from hilrig.replay import parse_specs
from hilrig.sweep import TaskResult, find_inputs, partition_files, plan, read_sweep
from hilrig.sweep import sweep as run_sweep
from hilrig.sweep.dataset import METRICS, Layout

ray = pytest.importorskip("ray")

RAY = Path(sys.executable).with_name("ray")
#: The whole module's bound: past it the watchdog kills both nodes (and the tests fail).
WATCHDOG_S = 240
START_TIMEOUT_S = 90


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Cluster:
    address: str
    head: subprocess.Popen[bytes]
    worker: subprocess.Popen[bytes]

    def kill_worker_node(self) -> None:
        _kill_session(self.worker, signal.SIGKILL)


def _node(args: list[str], temp: str, log: Path) -> subprocess.Popen[bytes]:
    command = [str(RAY), "start", "--block", "--num-cpus", "1", "--temp-dir", temp, *args]
    command += ["--node-ip-address", "127.0.0.1", "--disable-usage-stats"]
    command += ["--dashboard-agent-listen-port", str(free_port())]
    with log.open("wb") as out:
        return subprocess.Popen(
            command,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            env=os.environ.copy(),
        )


def _kill_session(process: subprocess.Popen[bytes], sig: signal.Signals) -> None:
    """``sig`` to every process of the session ``process`` leads (``ray start``, GCS, raylet,
    agents and every worker, whatever its process group), scanned until none is new."""
    signalled: set[int] = set()
    while members := {pid for pid in _pids() if _session(pid) == process.pid} - signalled:
        for pid in members:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
        signalled |= members


def _pids() -> list[int]:
    return [int(name) for name in os.listdir("/proc") if name.isdigit()]


def _session(pid: int) -> int:
    try:
        return os.getsid(pid)
    except (ProcessLookupError, PermissionError):
        return -1


def _alive_nodes() -> list[str]:
    return [n["NodeID"] for n in ray.nodes() if n["Alive"]]


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    with pytest.MonkeyPatch.context() as patch:  # nodes, this driver and the CLI's alike
        patch.setenv("RAY_AUTH_MODE", "disabled")  # loopback only; no token in ~/.ray needed
        patch.setenv("RAY_USAGE_STATS_ENABLED", "0")
        yield from _cluster(tmp_path_factory)


def _cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    logs = tmp_path_factory.mktemp("ray-logs")
    temps = [tempfile.mkdtemp(prefix="ray", dir="/tmp") for _ in range(2)]  # sockets: short paths
    port = free_port()
    address = f"127.0.0.1:{port}"
    head_args = ["--head", "--port", str(port), "--include-dashboard", "false"]
    head_args += ["--ray-client-server-port", str(free_port())]
    head = _node(head_args, temps[0], logs / "head.log")
    processes = [head]
    watchdog = threading.Timer(
        WATCHDOG_S, lambda: [_kill_session(p, signal.SIGKILL) for p in processes]
    )
    watchdog.start()
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), 1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, (logs / "head.log").read_text()
                assert head.poll() is None, (logs / "head.log").read_text()
                time.sleep(0.2)
        worker = _node(["--address", address], temps[1], logs / "worker.log")
        processes.append(worker)
        ray.init(address=address, logging_level="WARNING", log_to_driver=False)
        while len(_alive_nodes()) < 2:
            assert time.monotonic() < deadline, (logs / "worker.log").read_text()
            time.sleep(0.2)
        yield Cluster(address, head, worker)
    finally:
        watchdog.cancel()
        ray.shutdown()
        for process in processes:
            _kill_session(process, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                _kill_session(process, signal.SIGKILL)
                process.wait(timeout=10)
        time.sleep(1)  # the groups' last processes (raylet, gcs) end after ray start itself
        for process in processes:
            _kill_session(process, signal.SIGKILL)
        for temp in temps:
            shutil.rmtree(temp, ignore_errors=True)


def test_ray_on_the_cluster_writes_what_the_local_engine_writes(
    cluster: Cluster, tmp_path: Path
) -> None:
    sessions(tmp_path / "in", count=2)
    local = hilrig("sweep", str(tmp_path / "in"), *SWEEP, "-o", str(tmp_path / "local"))
    assert local.returncode == 0, local.stderr
    env = os.environ | {"RAY_ADDRESS": cluster.address, "COLUMNS": "80"}  # as users name it
    command = [
        "sweep",
        str(tmp_path / "in"),
        *SWEEP,
        "-o",
        str(tmp_path / "ray"),
        "--engine",
        "ray",
    ]
    result = subprocess.run(
        [str(Path(sys.executable).with_name("hilrig")), *command],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "6 tasks (2 sources x 3 parameter sets): 0 already done, 6 run on " in result.stdout
    assert " Ray node" in result.stdout
    pd.testing.assert_frame_equal(read_sweep(tmp_path / "ray"), read_sweep(tmp_path / "local"))
    assert len(partition_files(tmp_path / "ray")) == 6
    summary_tables = result.stdout.splitlines()[1:]  # from the tasks' sums Ray returned
    assert summary_tables[0].startswith("cartesian collisions per parameter set")
    assert summary_tables == local.stdout.splitlines()[1:]


def warm_up(node: str) -> None:
    """A worker of this driver on ``node`` with the sweep's code loaded (Ray keeps it for the
    driver's next tasks)."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    def load() -> str:
        import hilrig.sweep.engines  # noqa: F401

        return str(ray.get_runtime_context().get_node_id())

    strategy = NodeAffinitySchedulingStrategy(node, soft=False)
    remote = ray.remote(num_cpus=1, scheduling_strategy=strategy)(load)
    assert ray.get(remote.remote(), timeout=120) == node


def test_a_node_killed_mid_sweep_loses_no_result(cluster: Cluster, tmp_path: Path) -> None:
    inputs = [force_table(tmp_path / f"t{n}.parquet", 120.0, seed=n) for n in range(3)]
    tasks = plan(
        find_inputs(inputs),
        parse_specs(["adaptive"], sweeps=["adaptive.a1=5,10,20"]),
        closed_loop=False,
    )
    head = ray.get_runtime_context().get_node_id()  # the driver is attached to the head
    nodes = set(_alive_nodes())
    (worker_node,) = nodes - {head}
    warm_up(worker_node)  # its first worker, hilrig loaded: it takes tasks from the start
    seen: list[TaskResult] = []
    killed_after: list[int] = []
    killed_at_ns: list[int] = []

    def on_result(result: TaskResult) -> None:
        seen.append(result)
        if result.node == worker_node and not killed_after:
            cluster.kill_worker_node()  # raylet, its workers and agents: the node is gone
            killed_at_ns.append(time.time_ns())
            killed_after.append(len(seen))

    summary = run_sweep(
        tasks, tmp_path / "out", engine="ray", address=cluster.address, on_result=on_result
    )
    assert killed_after and killed_after[0] < len(tasks), [r.node for r in seen]
    assert summary.nodes == {head, worker_node}
    # The killed node wrote nothing after the kill: a result of it delivered later is one it
    # had finished (partitions in place) before; everything else ran on the head.
    layout = Layout(tmp_path / "out")
    late = [r for r in seen[killed_after[0] :] if r.node != head]
    assert {r.node for r in late} <= {worker_node}
    for r in late:
        written_ns = layout.partition(METRICS, r.source, r.run).stat().st_mtime_ns
        assert written_ns <= killed_at_ns[0], (r.source, r.run)
    assert sorted((r.source, r.run) for r in summary.results) == sorted(
        (t.source, t.run) for t in tasks
    )
    assert not [r for r in summary.results if r.error]
    assert len(partition_files(tmp_path / "out")) == len(tasks) == 9
    assert set(read_sweep(tmp_path / "out")["source"]) == {p.name for p in inputs}
