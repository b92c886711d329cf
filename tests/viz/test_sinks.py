"""A viewer's URL is checked by asking it: Rerun's own servers answer, anything else listening
there is named in one line (and never waited on for long)."""

from __future__ import annotations

import socket
from collections.abc import Callable
from contextlib import AbstractContextManager

import pytest
from servers import impostor, web_server

from hilrig.errors import ViewError
from hilrig.viz.sinks import WebServer, check_reachable, grpc_url, viewer_problem

NOT_RERUN = "nothing answering like a Rerun viewer there"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def test_rerun_serve_web_answers_as_a_rerun_server() -> None:
    """Rerun's own server (``rerun --serve-web``; ``rerun --save`` in tests/cli)."""
    server = WebServer(free_port(), free_port())
    try:
        assert viewer_problem(grpc_url(server.port)) == ""
        check_reachable(grpc_url(server.port), "--connect")
    finally:
        server.close()


Serving = Callable[[], AbstractContextManager[str]]


@pytest.mark.parametrize(
    ("serving", "why"),
    [
        (lambda: impostor(None), "no answer within 1 s"),
        (lambda: impostor(b"\x00\x15\xfe garbage\r\n"), "its answer is not HTTP"),
        (lambda: impostor(b"SSH-2.0-OpenSSH_9.2\r\n"), "its answer is not HTTP"),
        (lambda: impostor(b"HTTP/1.1 200 OK\r\n"), "its answer is not a whole HTTP head"),
        (web_server, "HTTP 501 text/html;charset=utf-8, not gRPC-web"),
        (
            lambda: impostor(
                b"HTTP/1.1 200 OK\r\ncontent-type: application/grpc-web+proto\r\n"
                b"grpc-status: 12\r\ncontent-length: 0\r\n\r\n"
            ),
            "a gRPC server without Rerun's message proxy",
        ),
    ],
)
def test_what_listens_there_but_is_not_rerun_is_named_in_one_line(
    serving: Serving, why: str
) -> None:
    with serving() as url:
        assert viewer_problem(url, 1.0) == f"{NOT_RERUN} ({why})"
        with pytest.raises(ViewError) as caught:
            check_reachable(url, "--connect", 1.0)
    assert str(caught.value) == f"--connect {url}: {NOT_RERUN} ({why})"


def test_where_nothing_listens_is_said_so() -> None:
    url = grpc_url(free_port())  # bound and released: nobody listens
    assert viewer_problem(url) == "no viewer listening there (Connection refused)"
