"""Rerun's own gRPC server saving what it receives to a file (``rerun --save``, no window), on
127.0.0.1: the real receiving end of a live view, for the tests and the session benchmark."""

from __future__ import annotations

import contextlib
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

from hilrig.errors import ViewError
from hilrig.viz.sinks import LOCALHOST, grpc_url, listening, rerun_binary

START_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 30.0


@contextlib.contextmanager
def rerun_save_server(saved: Path) -> Iterator[str]:
    """The server on a free loopback port, writing what it receives to ``saved``; its
    ``rerun+http`` URL. When the block ends: once ``saved`` has not grown for 1 s, Ctrl-C (it
    stops saving and exits). A server that has not exited ``STOP_TIMEOUT_S`` later is killed
    rather than left running (what it received is in the file by then; a server started with
    SIGINT ignored, as a script's background job is, would ignore Ctrl-C). Raises ViewError if
    it does not listen within ``START_TIMEOUT_S``."""
    with contextlib.closing(socket.socket()) as probe:
        probe.bind((LOCALHOST, 0))
        port = probe.getsockname()[1]
    command = [str(rerun_binary()), "--save", str(saved), "--port", str(port)]
    server = subprocess.Popen(
        [*command, "--bind", LOCALHOST], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not listening(port):
            if server.poll() is not None:
                raise ViewError(f"rerun --save exited with {server.returncode}")
            if time.monotonic() > deadline:
                raise ViewError(f"rerun --save did not listen on port {port}")
            time.sleep(0.05)
        yield grpc_url(port)
        wait_settled(saved)
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


def wait_settled(path: Path, quiet_s: float = 1.0, timeout_s: float = 60.0) -> None:
    """Until ``path`` exists and has not grown for ``quiet_s`` (a server writes what it gets
    as it gets it), or ``timeout_s`` has passed."""
    size, since = -1, time.monotonic()
    deadline = since + timeout_s
    while (size <= 0 or time.monotonic() - since < quiet_s) and time.monotonic() < deadline:
        time.sleep(0.1)
        now = path.stat().st_size if path.exists() else -1
        if now != size:
            size, since = now, time.monotonic()
