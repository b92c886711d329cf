"""ARCS wire formats, pure (no I/O): the two framings, the login text and the RTDE hello.

As observed against AUBO's own client, pyaubo-sdk 0.24.1 (docs/protocols.md, "ARCS"):

- JSON-RPC (a controller's TCP 30004): every message both ways is ``b"SOF\\x01"``, its body's
  length as uint32 big-endian, then the body (JSON-RPC 2.0, or the login text);
- RTDE (TCP 30010): ``b"SOF\\x00"``, uint16 big-endian length, a CBOR body; on connect the
  server first sends its hello, a JSON object followed by ``b"\\n\\n"``;
- the login text ``__login__\\n<user>\\n<token>\\n<client version>\\n``, where the token is the
  decimal population count of each byte of a fixed 20-byte key, the password's bytes and a fixed
  50-byte key (so it depends on the password only, and "a" and "b" give the same token).

:class:`FrameDecoder` takes a stream in chunks of any size and returns whole bodies: a partial
frame waits for its rest, bytes that are not a frame (no magic, or a length over the limit) are
skipped and counted, never raised.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

RPC_MAGIC = b"SOF\x01"
RTDE_MAGIC = b"SOF\x00"
RPC_LENGTH_BYTES = 4
RTDE_LENGTH_BYTES = 2
MAX_RPC_BODY_BYTES = 1 << 20  # longer announced lengths are taken for garbage
MAX_RTDE_BODY_BYTES = 0xFFFF

LOGIN_TAG = b"__login__\n"
LOGIN_SUCCEED = b"SUCCEED"
LOGIN_FAILED = b"FAILED"  # our choice: 0.24.1's login() does not read the reply's body
CLIENT_VERSION = "0.24.0"  # what pyaubo-sdk 0.24.1 writes as its version in the login text

# popcount digits of the key bytes the client wraps the password in (observed, not documented)
_TOKEN_PREFIX = "33535454353536643454"
_TOKEN_SUFFIX = "43435463466335333566235443434253142434333426365553"


def rpc_frame(body: bytes) -> bytes:
    """``body`` framed for the JSON-RPC port."""
    return RPC_MAGIC + len(body).to_bytes(RPC_LENGTH_BYTES, "big") + body


def rtde_frame(body: bytes) -> bytes:
    """``body`` (at most 65535 bytes) framed for the RTDE port."""
    return RTDE_MAGIC + len(body).to_bytes(RTDE_LENGTH_BYTES, "big") + body


class FrameDecoder:
    """Whole frame bodies out of a byte stream fed in arbitrary chunks.

    ``garbage_bytes`` counts bytes skipped because they were not part of a frame (no magic
    where one should start, or an announced length over ``max_body``).
    """

    def __init__(self, magic: bytes, length_bytes: int, max_body: int) -> None:
        self._magic = magic
        self._header = len(magic) + length_bytes
        self._max_body = max_body
        self._buf = bytearray()
        self.garbage_bytes = 0

    @classmethod
    def rpc(cls) -> FrameDecoder:
        """A decoder of the JSON-RPC framing."""
        return cls(RPC_MAGIC, RPC_LENGTH_BYTES, MAX_RPC_BODY_BYTES)

    @classmethod
    def rtde(cls) -> FrameDecoder:
        """A decoder of the RTDE framing."""
        return cls(RTDE_MAGIC, RTDE_LENGTH_BYTES, MAX_RTDE_BODY_BYTES)

    @property
    def buffered(self) -> int:
        """Bytes held back: the start of a frame whose rest has not arrived."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray) -> list[bytes]:
        """Take ``data``; return the bodies of the frames it completed, in order."""
        buf = self._buf
        buf += data
        bodies: list[bytes] = []
        magic, header = self._magic, self._header
        while buf:
            if not buf.startswith(magic):
                if len(buf) < len(magic) and magic.startswith(buf):
                    break  # a magic split across chunks
                self._skip_to_magic()
                continue
            if len(buf) < header:
                break
            length = int.from_bytes(buf[len(magic) : header], "big")
            if length > self._max_body:
                self._skip(1)  # not a frame after all: look for the next magic
                continue
            end = header + length
            if len(buf) < end:
                break
            bodies.append(bytes(buf[header:end]))
            del buf[:end]
        return bodies

    def _skip_to_magic(self) -> None:
        """Skip to the next magic, or all but a tail that may start one."""
        buf, magic = self._buf, self._magic
        found = buf.find(magic, 1)
        if found >= 0:
            self._skip(found)
            return
        keep = 0
        for size in range(min(len(magic), len(buf)) - 1, 0, -1):
            if buf.endswith(magic[:size]):
                keep = size
                break
        self._skip(len(buf) - keep)

    def _skip(self, count: int) -> None:
        del self._buf[:count]
        self.garbage_bytes += count


@dataclass(frozen=True)
class Login:
    """A login text's fields."""

    user: str
    token: str
    client_version: str


def is_login(body: bytes) -> bool:
    """True if ``body`` is a login text (not JSON, not CBOR)."""
    return body.startswith(LOGIN_TAG)


def parse_login(body: bytes) -> Login | None:
    """The fields of a login text; None if ``body`` is not a well-formed one."""
    if not is_login(body):
        return None
    try:
        lines = body.decode("utf-8").split("\n")
    except UnicodeDecodeError:
        return None
    if len(lines) != 5 or lines[4] != "":
        return None
    return Login(lines[1], lines[2], lines[3])


def login_token(password: str) -> str:
    """The token pyaubo-sdk 0.24.1 sends for ``password``."""
    digits = "".join(str(byte.bit_count()) for byte in password.encode("utf-8"))
    return _TOKEN_PREFIX + digits + _TOKEN_SUFFIX


def login_text(user: str, password: str, client_version: str = CLIENT_VERSION) -> bytes:
    """The login body a 0.24.1 client sends (for tests and raw clients)."""
    return f"__login__\n{user}\n{login_token(password)}\n{client_version}\n".encode()


def rtde_hello(
    outputs: Mapping[str, int],
    inputs: Mapping[str, int],
    *,
    protocol: str = "1",
    version: int = 1,
) -> bytes:
    """The JSON object an RTDE server sends first: its protocol, version (a string and a
    number: the client refuses other types) and its input and output maps (name: id)."""
    hello = {
        "protocol": protocol,
        "version": version,
        "input": dict(inputs),
        "output": dict(outputs),
    }
    return json.dumps(hello, separators=(",", ":")).encode() + b"\n\n"
