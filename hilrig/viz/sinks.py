"""Where a view goes: the desktop viewer, an ``.rrd`` file, a viewer or server at a URL, or a
web viewer served on localhost by Rerun's own server (``rerun --serve-web``).

A viewer's URL is checked by asking it (:func:`viewer_problem`): every Rerun gRPC server (the
desktop viewer, ``rerun --serve-web``, ``rerun --save``) also takes gRPC-web over HTTP/1.1, for
the web viewer, so one plain request to its message proxy, answered or not within a few seconds,
tells a Rerun server from anything else listening there."""

from __future__ import annotations

import contextlib
import os
import socket
import ssl
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from urllib.parse import urlsplit

import rerun as rr
import rerun.blueprint as rrb
import rerun_cli

from hilrig.errors import ViewError

APPLICATION_ID = "hilrig"
LOCALHOST = "127.0.0.1"
GRPC_PORT = 9876  # Rerun's defaults
WEB_PORT = 9090
RRD_SUFFIX = ".rrd"
URL_SCHEMES = {"rerun": 443, "rerun+http": 80, "rerun+https": 443}  # and their default ports
CONNECT_TIMEOUT_S = 3.0  # a viewer must accept a connection and answer within this
#: A server-streaming call of Rerun's message proxy: its answer's head comes at once.
PROBE_PATH = "/rerun.sdk_comms.v1alpha1.MessageProxyService/ReadTables"
PROBE_HEAD_BYTES = 16384  # an answer's head read at most
HTTP_PREFIX = b"HTTP/1."
NOT_RERUN = "nothing answering like a Rerun viewer there"
NO_DISPLAY = (
    "no display for the Rerun viewer (DISPLAY and WAYLAND_DISPLAY are not set): save to a file "
    "or use the web viewer or a viewer's URL"
)


class SinkKind(StrEnum):
    SPAWN = "spawn"  # start (or reuse) the desktop viewer on a port
    SAVE = "save"  # write an .rrd file
    CONNECT = "connect"  # stream to a running viewer or server (gRPC URL)
    WEB = "web"  # serve the web viewer on localhost


@dataclass(frozen=True)
class Sink:
    """A destination: ``path`` for SAVE, ``url`` for CONNECT, ports for SPAWN and WEB."""

    kind: SinkKind
    path: Path | None = None
    url: str | None = None
    port: int = GRPC_PORT
    web_port: int = WEB_PORT


def check_rrd_path(path: Path | None, what: str) -> Path:
    """``path`` if it names an ``.rrd`` file in an existing, writable folder; else ViewError
    naming ``what`` (the option or role) and the path. A file already there is the caller's to
    refuse or replace (:func:`hilrig.outputs.check_new_file`)."""
    if path is None or path.suffix.lower() != RRD_SUFFIX:
        raise ViewError(f"{what} {path}: the name must end in {RRD_SUFFIX}")
    if path.is_dir():
        raise ViewError(f"{what} {path}: is a directory")
    if not path.parent.is_dir():
        raise ViewError(f"{what} {path}: directory {path.parent} does not exist")
    if not os.access(path.parent, os.W_OK):
        raise ViewError(f"{what} {path}: directory {path.parent} is not writable")
    return path


def grpc_address(url: str, what: str = "URL") -> tuple[str, int]:
    """Host and port of a Rerun gRPC URL (``rerun+http://HOST:PORT/proxy``); else ViewError
    naming ``what`` and the URL."""
    parts = urlsplit(url)
    try:
        port = parts.port or URL_SCHEMES.get(parts.scheme, 0)
    except ValueError:
        port = 0
    if parts.scheme not in URL_SCHEMES or not parts.hostname or parts.path != "/proxy" or not port:
        raise ViewError(
            f"{what} {url!r}: expected rerun+http://HOST:PORT/proxy (or rerun://, rerun+https://)"
        )
    return parts.hostname, port


def check_reachable(url: str, what: str = "URL", timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Raises ViewError (one line, naming ``what`` and ``url``) unless a Rerun viewer or server
    answers at the gRPC ``url`` within ``timeout_s`` (:func:`viewer_problem`): Rerun itself
    would retry for minutes, or wait for an answer that never comes."""
    grpc_address(url, what)
    problem = viewer_problem(url, timeout_s)
    if problem:
        raise ViewError(f"{what} {url}: {problem}")


def viewer_problem(url: str, timeout_s: float = CONNECT_TIMEOUT_S) -> str:
    """Why no Rerun viewer or server answers at the gRPC ``url`` within ``timeout_s`` (one
    line), or "" if one does: something must accept a connection and answer a gRPC-web call of
    Rerun's message proxy (:data:`PROBE_PATH`) as a Rerun server does."""
    host, port = grpc_address(url)
    deadline = time.monotonic() + timeout_s
    try:
        connection = socket.create_connection((host, port), timeout=timeout_s)
    except TimeoutError:
        return f"no answer within {timeout_s:g} s"
    except OSError as err:
        return f"no viewer listening there ({err.strerror or type(err).__name__})"
    try:
        with connection:
            head = _probe(connection, host, port, urlsplit(url).scheme != "rerun+http", deadline)
    except TimeoutError:
        return f"{NOT_RERUN} (no answer within {timeout_s:g} s)"
    except ssl.SSLError as err:
        return f"{NOT_RERUN} (TLS: {err.reason or type(err).__name__})"
    except OSError as err:
        return f"{NOT_RERUN} ({err.strerror or type(err).__name__})"
    reason = _not_rerun(head)
    return f"{NOT_RERUN} ({reason})" if reason else ""


def _probe(connection: socket.socket, host: str, port: int, tls: bool, deadline: float) -> bytes:
    """Send the gRPC-web call (over TLS if ``tls``); the answer's head (status line and headers,
    up to :data:`PROBE_HEAD_BYTES`), or what came before the connection closed."""
    request = (
        f"POST {PROBE_PATH} HTTP/1.1\r\nHost: {host}:{port}\r\n"
        "Content-Type: application/grpc-web+proto\r\nX-Grpc-Web: 1\r\n"
        "Content-Length: 5\r\nConnection: close\r\n\r\n"
    ).encode("ascii") + bytes(5)  # one empty message: flag 0, length 0
    _left(connection, deadline)
    stream = connection
    if tls:
        stream = ssl.create_default_context().wrap_socket(connection, server_hostname=host)
    head = b""
    with stream:
        _left(stream, deadline)
        stream.sendall(request)
        while _incomplete(head):
            try:
                _left(stream, deadline)
                chunk = stream.recv(4096)
            except TimeoutError:
                if head:
                    break  # judged by what came
                raise
            if not chunk:
                break
            head += chunk
    return head


def _incomplete(head: bytes) -> bool:
    """More of an answer's head may tell: no end of its headers yet, not too long, and nothing
    yet that could not begin an HTTP answer."""
    http = HTTP_PREFIX.startswith(head[: len(HTTP_PREFIX)])
    return http and b"\r\n\r\n" not in head and len(head) < PROBE_HEAD_BYTES


def _left(stream: socket.socket, deadline: float) -> None:
    """Give ``stream``'s next call the time left until ``deadline``; TimeoutError if none is."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError
    stream.settimeout(left)


def _not_rerun(head: bytes) -> str:
    """Why ``head`` is not a Rerun server's answer to the probe ("" if it is)."""
    if not head:
        return "it closed the connection without answering"
    lines = head.split(b"\r\n\r\n", 1)[0].decode("latin-1").split("\r\n")
    status = lines[0].split()
    if len(status) < 2 or not status[0].startswith(HTTP_PREFIX.decode()):
        return "its answer is not HTTP"
    if b"\r\n\r\n" not in head:
        return "its answer is not a whole HTTP head"
    fields = (line.partition(":") for line in lines[1:])
    headers = {name.strip().lower(): value.strip() for name, _, value in fields}
    kind = headers.get("content-type", "")
    if status[1] != "200" or not kind.startswith("application/grpc-web"):
        return f"HTTP {status[1]} {kind or 'without a content type'}, not gRPC-web"
    if headers.get("grpc-status") == "12":  # UNIMPLEMENTED
        return "a gRPC server without Rerun's message proxy"
    return ""


def check_display(port: int = GRPC_PORT) -> None:
    """Raises ViewError at once when the desktop viewer could not open a window: on Linux,
    neither DISPLAY nor WAYLAND_DISPLAY is set (and no viewer already listens on ``port``)."""
    if not sys.platform.startswith("linux") or listening(port):
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ViewError(NO_DISPLAY)


def grpc_url(port: int, host: str = LOCALHOST) -> str:
    return f"rerun+http://{host}:{port}/proxy"


def web_url(web_port: int, port: int) -> str:
    return f"http://{LOCALHOST}:{web_port}/?url={grpc_url(port)}"


class WebServer:
    """``rerun --serve-web`` bound to 127.0.0.1: Rerun's gRPC proxy and its web viewer."""

    def __init__(self, port: int, web_port: int) -> None:
        command = [str(rerun_binary()), "--serve-web", "--bind", LOCALHOST, "--port", str(port)]
        command += ["--web-viewer-port", str(web_port)]
        self.port, self.web_port = port, web_port
        # its stderr: a pipe nobody reads could fill; closed by close()
        self._log = tempfile.TemporaryFile(mode="w+")  # noqa: SIM115
        try:  # a session of its own: a terminal's Ctrl-C reaches hilrig, which stops it in turn
            self.process = subprocess.Popen(
                with_parent(command),
                stdout=subprocess.DEVNULL,
                stderr=self._log,
                text=True,
                start_new_session=True,
            )
        except OSError as err:
            self._log.close()
            raise ViewError(f"cannot start the Rerun server: {err}") from err
        try:
            self._wait_listening()
        except BaseException:  # Ctrl-C too: never left running
            self.close()
            raise

    def _wait_listening(self, timeout_s: float = 20.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if problem := self.exited():
                raise ViewError(problem)
            if listening(self.port) and listening(self.web_port):
                return
            time.sleep(0.05)
        self.close()
        raise ViewError(
            f"the Rerun web server did not listen on ports {self.port} and {self.web_port} "
            f"within {timeout_s:g} s"
        )

    @property
    def url(self) -> str:
        return web_url(self.web_port, self.port)

    def exited(self) -> str:
        """Why the server ended ("" while it runs): its exit code and last words."""
        if self.process.poll() is None:
            return ""
        if self._log.closed:
            return f"the Rerun web server exited with code {self.process.returncode}"
        self._log.seek(0)
        last = [line.strip() for line in self._log.read().splitlines() if line.strip()][-1:]
        return (
            f"the Rerun web server exited with code {self.process.returncode}: "
            f"{last[0] if last else 'no output'}"
        )

    def close(self) -> None:
        """Stop the server (SIGTERM, then SIGKILL after 5 s) and wait for it."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()


VIEWER_SETTLE_S = 3.0  # a new viewer must still run this long after it listens


def spawn_viewer(port: int, timeout_s: float = 20.0) -> None:
    """Start the desktop viewer listening on ``port`` (detached: it outlives this process), or
    use the one already there. Raises ViewError, with the viewer's last words, if it exits or
    does not listen within ``timeout_s`` (no display: use a file, the web viewer or a URL). A
    viewer without a display listens for a moment before it dies: a new one must still run
    ``VIEWER_SETTLE_S`` after it listens."""
    if listening(port):
        return
    check_display(port)
    command = [str(rerun_binary()), "--port", str(port), "--expect-data-soon"]
    with tempfile.TemporaryFile(mode="w+") as log:
        try:
            viewer = subprocess.Popen(
                command, stdout=log, stderr=log, start_new_session=True, text=True
            )
        except OSError as err:
            raise ViewError(f"cannot start the Rerun viewer: {err}") from err
        deadline = time.monotonic() + timeout_s
        settled = None  # the viewer listens before it opens its window, and may die then
        while settled is None or time.monotonic() < settled:
            if viewer.poll() is not None or time.monotonic() > deadline:
                log.seek(0)
                words = [line.strip() for line in log.read().splitlines() if line.strip()]
                raise ViewError(
                    f"the Rerun viewer did not start ({words[-1] if words else 'no output'});"
                    " without a display, save to a file or use the web viewer or a viewer's URL"
                )
            if settled is None and listening(port):
                settled = time.monotonic() + VIEWER_SETTLE_S
            time.sleep(0.05)


#: Runs ``argv[2:]`` bound to the process ``argv[1]``: Linux ends it (SIGTERM) when that process
#: ends, however it ends, and it does not start if that process is gone already.
WITH_PARENT = (
    "import ctypes, os, signal, sys\n"
    "ctypes.CDLL(None).prctl(1, signal.SIGTERM, 0, 0, 0)\n"
    "if os.getppid() != int(sys.argv[1]): raise SystemExit(1)\n"
    "os.execv(sys.argv[2], sys.argv[2:])\n"
)


def with_parent(command: list[str]) -> list[str]:
    """``command`` made to end with this process on Linux (``prctl(PR_SET_PDEATHSIG)`` before
    it starts, :data:`WITH_PARENT`); as it is elsewhere."""
    if not sys.platform.startswith("linux"):
        return command
    return [sys.executable, "-c", WITH_PARENT, str(os.getpid()), *command]


def rerun_binary() -> Path:
    """The Rerun CLI's executable itself (``RERUN_CLI_PATH`` if set), not the ``rerun`` script
    that wraps it: a signal to the script would not reach the server it started."""
    override = os.environ.get("RERUN_CLI_PATH")
    path = Path(override) if override else Path(rerun_cli.__file__).with_name("rerun")
    if not path.is_file():
        raise ViewError(f"no Rerun CLI at {path}: reinstall rerun-sdk")
    return path


def listening(port: int) -> bool:
    """Whether something accepts TCP connections on 127.0.0.1:``port``."""
    with contextlib.closing(socket.socket()) as s:
        s.settimeout(0.2)
        return s.connect_ex((LOCALHOST, port)) == 0


def open_stream(
    sink: Sink, blueprint: rrb.Blueprint, *, recording_id: str | None = None
) -> tuple[rr.RecordingStream, WebServer | None]:
    """A recording stream going to ``sink`` with ``blueprint`` as its default layout, and the
    web server it started (WEB only; close it when done). Raises ViewError."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    server = None
    try:
        match sink.kind:
            case SinkKind.SAVE:
                assert sink.path is not None
                rec.save(sink.path, default_blueprint=blueprint)
            case SinkKind.CONNECT:
                check_reachable(sink.url or "", "viewer")
                rec.connect_grpc(sink.url, default_blueprint=blueprint)
            case SinkKind.SPAWN:
                spawn_viewer(sink.port)
                rec.connect_grpc(grpc_url(sink.port), default_blueprint=blueprint)
            case SinkKind.WEB:
                server = WebServer(sink.port, sink.web_port)
                rec.connect_grpc(grpc_url(sink.port), default_blueprint=blueprint)
    except (OSError, RuntimeError, ValueError) as err:
        if server is not None:
            server.close()
        target = sink.path or sink.url or sink.kind.value
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise ViewError(f"cannot open the view ({target}): {first}") from err
    return rec, server
