"""ROS 2 ``.msg`` definitions: parsing, and the concatenated text that MCAP schemas carry.

A schema of the MCAP ``ros2`` profile holds the top-level definition followed by every
definition it depends on, each introduced by a line of 80 ``=`` and ``MSG: pkg/Type`` (the text
rosbag2 writes). Readers such as Rerun cannot decode a channel whose schema leaves out a
dependency, so :func:`full_definition` always includes all of them, down to
``builtin_interfaces/Time``.

The definitions hilrig writes ship as ``.msg`` files under ``hilrig/recording/msgdefs``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from importlib import resources

from hilrig.errors import RecordingError

PRIMITIVE_TYPES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "float32",
        "float64",
        "string",
        "wstring",
    }
)
TIME_TYPES = frozenset({"builtin_interfaces/Time", "builtin_interfaces/Duration"})
SEPARATOR = "=" * 80

_FIELD = re.compile(
    r"^(?P<type>[A-Za-z_][\w/]*)(?:<=\d+)?(?P<array>\[(?P<bound><=)?(?P<size>\d*)\])?$"
)
_IDENTIFIER = re.compile(r"[A-Za-z]\w*")
_SECTION_SPLIT = re.compile(r"^={3,}\s*$", flags=re.MULTILINE)
_MSG_LINE = re.compile(r"^MSG:\s*(\S+)\s*$", flags=re.MULTILINE)


@dataclass(frozen=True)
class Field:
    """One field of a message: ``type`` is a primitive name or a resolved ``pkg/Type``.

    ``array_size`` is None for a scalar, the length of a fixed array ``T[N]``, or -1 for a
    sequence ``T[]`` / ``T[<=N]`` (whose length is serialized with each message).
    """

    name: str
    type: str
    array_size: int | None = None

    @property
    def is_sequence(self) -> bool:
        return self.array_size == -1


@dataclass(frozen=True)
class MessageDef:
    """A parsed message definition: its ``pkg/Type`` name, fields in order and source text."""

    name: str
    fields: tuple[Field, ...]
    text: str


MessageDefs = dict[str, MessageDef]


def short_name(type_name: str) -> str:
    """``geometry_msgs/msg/Wrench`` -> ``geometry_msgs/Wrench`` (the key used in schemas)."""
    parts = type_name.split("/")
    return f"{parts[0]}/{parts[-1]}" if len(parts) > 1 else type_name


def _resolve(type_token: str, package: str) -> str:
    if type_token in PRIMITIVE_TYPES:
        return type_token
    if "/" in type_token:
        return short_name(type_token)
    if type_token == "Header":  # the one short name ROS 1 style definitions still use
        return "std_msgs/Header"
    return f"{package}/{type_token}"


def parse_message(name: str, text: str) -> MessageDef:
    """Parse the text of one ``.msg`` definition named ``pkg/Type``; constants are skipped.

    Raises RecordingError on a line that is not a field, constant or comment.
    """
    name = short_name(name)
    package = name.split("/")[0]
    fields: list[Field] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        rest = line[len(tokens[0]) :].strip()
        if "=" in rest and _IDENTIFIER.fullmatch(rest.split("=", 1)[0].strip()):
            continue  # a constant: TYPE NAME=VALUE
        if len(tokens) < 2 or not _IDENTIFIER.fullmatch(tokens[1]):
            raise RecordingError(f"message definition {name}: cannot parse line {raw.strip()!r}")
        match = _FIELD.match(tokens[0])
        if match is None:
            raise RecordingError(f"message definition {name}: bad field type {tokens[0]!r}")
        array_size: int | None = None
        if match["array"]:
            array_size = -1 if match["bound"] or not match["size"] else int(match["size"])
        fields.append(Field(tokens[1], _resolve(match["type"], package), array_size))
    return MessageDef(name, tuple(fields), text)


def parse_schema(name: str, text: str) -> MessageDefs:
    """Parse a concatenated ``ros2msg`` schema into its definitions, keyed by ``pkg/Type``."""
    defs: MessageDefs = {}
    current = short_name(name)
    for section in _SECTION_SPLIT.split(text):
        match = _MSG_LINE.search(section)
        if match:
            current = short_name(match[1])
            section = _MSG_LINE.sub("", section, count=1)
        defs[current] = parse_message(current, section)
    return defs


@cache
def packaged_message(type_name: str) -> MessageDef:
    """The definition of ``pkg/Type`` shipped in ``hilrig/recording/msgdefs``.

    Raises RecordingError when hilrig ships no such definition.
    """
    package, _, message = short_name(type_name).partition("/")
    resource = resources.files("hilrig.recording") / "msgdefs" / package / "msg" / f"{message}.msg"
    try:
        text = resource.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise RecordingError(f"no packaged message definition for {type_name}") from err
    return parse_message(type_name, text)


def dependencies(type_name: str) -> list[str]:
    """Every message type ``type_name`` uses, depth first, each once (``pkg/Type`` names)."""
    seen: list[str] = []

    def visit(name: str) -> None:
        for field in packaged_message(name).fields:
            if field.type not in PRIMITIVE_TYPES and field.type not in seen:
                seen.append(field.type)
                visit(field.type)

    visit(type_name)
    return seen


@cache
def full_definition(type_name: str) -> str:
    """The schema text of ``type_name``: its definition, then each dependency after a separator."""
    parts = [packaged_message(type_name).text.rstrip("\n")]
    for dep in dependencies(type_name):
        parts.append(f"{SEPARATOR}\nMSG: {dep}\n{packaged_message(dep).text.rstrip(chr(10))}")
    return "\n".join(parts) + "\n"


def packaged_defs(type_name: str) -> MessageDefs:
    """``type_name`` and its dependencies, parsed, keyed by ``pkg/Type``."""
    names = [short_name(type_name), *dependencies(type_name)]
    return {name: packaged_message(name) for name in names}
