"""``hilrig sweep --engine ray --address`` where something listens that is not Ray: refused in
one line within seconds, before any work (nothing written), with none of Ray's own log lines.
Ray's client alone retried such an address for minutes, printing its warnings."""

from __future__ import annotations

import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from sweep_helpers import HILRIG, force_table

grpc = pytest.importorskip("grpc")
pytest.importorskip("ray")

#: A hang's bound, not a timing requirement: the check itself gives up after 3 s.
ENDED_S = 30.0


@contextmanager
def listener(answer: bytes | None) -> Iterator[str]:
    """A loopback TCP server that accepts every connection and answers ``answer`` (None:
    stays silent); its HOST:PORT."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    server.settimeout(0.2)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except OSError:
                continue
            held.append(connection)
            if answer is not None:
                connection.sendall(answer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        for connection in held:
            connection.close()
        server.close()


@contextmanager
def plain_grpc_server() -> Iterator[str]:
    """A real gRPC server with no service at all (every call: UNIMPLEMENTED)."""
    from concurrent.futures import ThreadPoolExecutor

    server = grpc.server(ThreadPoolExecutor(1))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        yield f"127.0.0.1:{port}"
    finally:
        server.stop(None)


def sweep_at(address: str, tmp_path: Path) -> tuple[subprocess.CompletedProcess[str], float]:
    table = force_table(tmp_path / "f.parquet", 3.0)
    command = [str(HILRIG), "sweep", str(table), "-c", "adaptive", "-o", str(tmp_path / "out")]
    command += ["--engine", "ray", "--address", address]
    start = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    return result, time.monotonic() - start


@pytest.mark.parametrize(
    ("answer", "why"),
    [
        (None, "nothing answering like a Ray cluster there (no answer within 3 s)"),
        (
            b"HTTP/1.1 400 Bad Request\r\n\r\n",
            "nothing answering like a Ray cluster there (it does not answer gRPC)",
        ),
    ],
    ids=["silent", "http"],
)
def test_a_listener_that_is_not_ray_is_refused_in_one_line(
    tmp_path: Path, answer: bytes | None, why: str
) -> None:
    with listener(answer) as address:
        result, took_s = sweep_at(address, tmp_path)
    assert took_s < ENDED_S, f"took {took_s:.1f} s"
    assert (result.returncode, result.stdout) == (2, ""), (took_s, result.stderr)
    assert result.stderr == (
        f"error: --address {address}: {why}; start one with `ray start --head`, or check the "
        "address\n"
    ), f"took {took_s:.1f} s"
    assert not (tmp_path / "out").exists()  # checked before any work: no sweep.json


def test_a_grpc_server_that_is_not_ray_is_refused_in_one_line(tmp_path: Path) -> None:
    with plain_grpc_server() as address:
        result, took_s = sweep_at(address, tmp_path)
    assert (result.returncode, result.stdout) == (2, ""), (took_s, result.stderr)
    assert result.stderr == (
        f"error: --address {address}: a gRPC server there, not a Ray cluster; start one with "
        "`ray start --head`, or check the address\n"
    ), f"took {took_s:.1f} s"
    assert not (tmp_path / "out").exists()
