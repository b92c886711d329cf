"""The emulated controller's JSON-RPC port (a real one's TCP 30004), a device of the slot loop.

Requests are answered as they arrive (the loop serves its sockets at the start of each slot),
several clients at once. The order a 0.24.1 client follows: ``SystemInfo.getInterfaceVersionCode``
(answered before login), the login text, then JSON-RPC 2.0 calls (rpc_methods.py).

A login with a known user and the token of its password is answered ``SUCCEED``. Any other
login (or one refused by the ``refuse_login`` fault) is answered ``FAILED``; since 0.24.1's
``login()`` does not read that body, the connection then answers its next request (the client's
own ``getRobotNames``) with the error ``-32000 Login failed: wrong user or password`` and closes:
the client's ``login()`` raises ``AuboException("getRobotNames-getRobotNames--32000: Login
failed: wrong user or password")`` at once, instead of waiting out a request timeout. A call
before login other than the version is answered ``-32000 Not logged in``.
"""

from __future__ import annotations

import json

from hilrig.emulator.arcs.controller import ArcsController
from hilrig.emulator.arcs.links import LinkServer
from hilrig.emulator.arcs.rpc_methods import (
    BEFORE_LOGIN,
    INVALID_REQUEST,
    LOGIN_FAILED_MESSAGE,
    NOT_LOGGED_IN,
    NOT_LOGGED_IN_MESSAGE,
    PARSE_ERROR,
    RpcError,
    call,
)
from hilrig.emulator.arcs.wire import (
    LOGIN_FAILED,
    LOGIN_SUCCEED,
    FrameDecoder,
    parse_login,
    rpc_frame,
)

_LOGGED_IN, _REFUSED = "logged in", "refused"


class EmulatedArcsRpcServer(LinkServer):
    """ARCS's JSON-RPC server over the emulated controller ``arcs``."""

    thread_name = "arcs-rpc"

    def __init__(self, arcs: ArcsController, *, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__(host, port)
        self._arcs = arcs
        self._epoch = arcs.link_epoch
        self._state: dict[int, str] = {}  # per client: absent (not logged in), or a state
        self.requests = 0  # JSON-RPC requests answered (results and errors)
        self.errors_sent = 0  # of them, answered with an error object

    def tick(self, slot_ns: int) -> None:
        """Close every client after a drop_links fault; push out unsent replies."""
        if self._arcs.link_epoch != self._epoch:
            self._epoch = self._arcs.link_epoch
            self.drop_all()
        for fd, link in list(self.links.items()):
            if link.out.unsent:
                self.flush(fd)

    def _decoder(self) -> FrameDecoder:
        return FrameDecoder.rpc()

    def _greet(self, fd: int) -> None:
        self._state.pop(fd, None)  # a new client on a reused descriptor

    def _received(self, fd: int, body: bytes) -> None:
        login = parse_login(body)
        if login is not None or body.startswith(b"__login__"):
            ok = login is not None and self._arcs.login(login.user, login.token)
            self._state[fd] = _LOGGED_IN if ok else _REFUSED
            self.send(fd, rpc_frame(LOGIN_SUCCEED if ok else LOGIN_FAILED))
            return
        request_id: object = None
        try:
            request = json.loads(body)
            if not isinstance(request, dict) or not isinstance(request.get("method"), str):
                raise RpcError(INVALID_REQUEST, "Invalid Request")
            request_id = request.get("id")
            result = self._answer(fd, request["method"], request.get("params"))
            reply: dict[str, object] = {"id": request_id, "jsonrpc": "2.0", "result": result}
        except RpcError as error:
            reply = {"id": request_id, "jsonrpc": "2.0", "error": error.as_json()}
            self.errors_sent += 1
        except (ValueError, RecursionError):  # not JSON (or nested past the parser's depth)
            reply = {
                "id": None,
                "jsonrpc": "2.0",
                "error": {"code": PARSE_ERROR, "message": "Parse error"},
            }
            self.errors_sent += 1
        self.requests += 1
        self.send(fd, rpc_frame(json.dumps(reply, separators=(",", ":")).encode()))

    def _answer(self, fd: int, method: str, params: object) -> object:
        state = self._state.get(fd)
        if state == _REFUSED:
            self.links[fd].closing = True
            raise RpcError(NOT_LOGGED_IN, LOGIN_FAILED_MESSAGE)
        if state is None and method not in BEFORE_LOGIN:
            raise RpcError(NOT_LOGGED_IN, NOT_LOGGED_IN_MESSAGE)
        return call(self._arcs, method, params)

    def _close(self, fd: int) -> None:
        self._state.pop(fd, None)
        super()._close(fd)
