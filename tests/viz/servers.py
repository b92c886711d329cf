"""Real loopback servers: Rerun's own gRPC server saving to a file, and servers that are not
Rerun viewers, for the checks of a viewer's URL."""

from __future__ import annotations

import contextlib
import http.server
import signal
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from hilrig.viz.sinks import rerun_binary


@contextlib.contextmanager
def impostor(answer: bytes | None) -> Iterator[str]:
    """A TCP server on 127.0.0.1 that accepts every connection, sends ``answer`` at once (None:
    nothing, ever) and keeps it open until the block ends; its ``rerun+http`` URL."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(0.1)
    taken: list[socket.socket] = []
    done = threading.Event()

    def serve() -> None:
        while not done.is_set():
            try:
                connection, _ = listener.accept()
            except TimeoutError:
                continue
            taken.append(connection)
            if answer is not None:
                connection.sendall(answer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"rerun+http://127.0.0.1:{listener.getsockname()[1]}/proxy"
    finally:
        done.set()
        thread.join()
        for connection in taken:
            connection.close()
        listener.close()


@contextlib.contextmanager
def web_server() -> Iterator[str]:
    """Python's own HTTP server on 127.0.0.1 (it answers POST with 501); its ``rerun+http``
    URL."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"rerun+http://127.0.0.1:{server.server_address[1]}/proxy"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


@contextlib.contextmanager
def rerun_save_server(saved: Path) -> Iterator[str]:
    """Rerun's own gRPC server (``rerun --save``, no window) on 127.0.0.1, writing what it
    receives to ``saved``; its ``rerun+http`` URL. When the block ends: once ``saved`` has not
    grown for 1 s, Ctrl-C (it stops saving and exits). A server that has not exited 30 s later
    is killed rather than left running (what it received is in the file by then; a server that
    ignores Ctrl-C is what tests/conftest.py prevents)."""
    with contextlib.closing(socket.socket()) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    command = [str(rerun_binary()), "--save", str(saved), "--port", str(port)]
    server = subprocess.Popen(
        [*command, "--bind", "127.0.0.1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 30
        while socket.socket().connect_ex(("127.0.0.1", port)) != 0:
            assert time.monotonic() < deadline, f"rerun did not listen on {port}"
            assert server.poll() is None, f"rerun exited with {server.returncode}"
            time.sleep(0.05)
        yield f"rerun+http://127.0.0.1:{port}/proxy"
        wait_settled(saved)
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


def wait_settled(path: Path, quiet_s: float = 1.0, timeout_s: float = 60.0) -> None:
    """Until ``path`` exists and has not grown for ``quiet_s`` (a server writes what it gets
    as it gets it)."""
    size, since = -1, time.monotonic()
    deadline = since + timeout_s
    while (size <= 0 or time.monotonic() - since < quiet_s) and time.monotonic() < deadline:
        time.sleep(0.1)
        now = path.stat().st_size if path.exists() else -1
        if now != size:
            size, since = now, time.monotonic()
