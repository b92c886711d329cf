"""Real loopback servers that are not Rerun viewers, for the checks of a viewer's URL (Rerun's
own server saving to a file is :mod:`hilrig.viz.save_server`)."""

from __future__ import annotations

import contextlib
import http.server
import socket
import threading
from collections.abc import Iterator


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
