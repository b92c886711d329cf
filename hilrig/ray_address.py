"""Where a sweep's Ray cluster is, and whether one answers there: checked in a few seconds,
before any work and before anything heavy is imported (``hilrig sweep --engine ray``).

Ray's own client, given an address where no Ray head answers, retries for minutes and prints
its warnings on the terminal; :func:`check_reachable` asks once, with a deadline, and says why
in one line. Ray itself is not imported here (:func:`require_ray` only looks for it).
"""

from __future__ import annotations

import importlib.util
import os
import socket
import time

from hilrig.errors import SweepError

INSTALL_HINT = "pip install 'hilrig[ray]'"
#: Seconds an address has to accept a connection and answer as a Ray head.
CONNECT_TIMEOUT_S = 3.0
#: A call every Ray head answers (its GCS; a Ray Client server for ``ray://``), made with an
#: empty request: what matters is who answers, not the answer.
GCS_PROBE = "/ray.rpc.NodeInfoGcsService/GetClusterId"
CLIENT_PROBE = "/ray.rpc.RayletDriver/ClusterInfo"
NOT_RAY = "nothing answering like a Ray cluster there"


def require_ray() -> None:
    """SweepError (one line, how to install it) when Ray is not installed."""
    if importlib.util.find_spec("ray") is None:
        raise SweepError(f"--engine ray needs Ray, which is not installed: {INSTALL_HINT}")


def cluster_address(address: str | None) -> str | None:
    """The cluster to join: ``address``, else ``RAY_ADDRESS``, else None (a local instance)."""
    return address or os.environ.get("RAY_ADDRESS") or None


def check_reachable(address: str | None, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse, in one line and within about ``timeout_s``, a ``HOST:PORT`` address (``ray://``
    too) where no Ray head answers (:func:`ray_problem`); ``auto`` and no address are left to
    Ray."""
    if address is None or address == "auto":
        return
    shown = address if address == os.environ.get("RAY_ADDRESS") else f"--address {address}"
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise SweepError(f"{shown}: expected HOST:PORT of a Ray head (e.g. 10.0.0.5:6379)")
    deadline = time.monotonic() + timeout_s
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout_s).close()
    except OSError as err:
        problem = f"no Ray cluster answers there ({err.strerror or type(err).__name__})"
    else:
        client = address.startswith("ray://")
        problem = ray_problem(f"{host}:{port}", client, deadline - time.monotonic())
    if problem:
        raise SweepError(
            f"{shown}: {problem}; start one with `ray start --head`, or check the address"
        )


def ray_problem(target: str, client: bool, timeout_s: float) -> str:
    """Why nothing at ``target`` answers as a Ray head within ``timeout_s`` (one line), or ""
    if something does: a gRPC server must answer :data:`GCS_PROBE` (:data:`CLIENT_PROBE` for a
    Ray Client server) with anything but "not implemented" (a refusal without Ray's token, or
    an error about the empty request, is Ray answering). gRPC comes with Ray."""
    import grpc

    method = CLIENT_PROBE if client else GCS_PROBE
    with grpc.insecure_channel(target) as channel:
        try:
            channel.unary_unary(method)(b"", timeout=max(timeout_s, 0.1))
        except grpc.RpcError as err:
            code = err.code()
            if code is grpc.StatusCode.DEADLINE_EXCEEDED:
                return f"{NOT_RAY} (no answer within {timeout_s:.0f} s)"
            if code is grpc.StatusCode.UNIMPLEMENTED:
                return "a gRPC server there, not a Ray cluster"
            if code is grpc.StatusCode.UNAVAILABLE:
                return f"{NOT_RAY} (it does not answer gRPC)"
    return ""
