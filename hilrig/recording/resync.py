"""Find where records start again after damage: the next offset holding a record that parses.

Records are parsed exactly (:mod:`.parse`), so random bytes almost never pass for one. To stay
fast over megabytes of compressed data, candidates are picked with numpy first: a known opcode
followed by a length below 4 GiB that fits in what is left (its four high bytes zero).
"""

from __future__ import annotations

import mmap

import numpy as np

from hilrig.recording import parse as p
from hilrig.recording.mcap_records import RECORD_HEADER, Op

_WINDOW = 1 << 20
_OPCODES = np.array(sorted(p.KNOWN_OPS - {Op.HEADER}), dtype=np.uint8)
_PARSERS = {
    Op.SCHEMA: p.parse_schema,
    Op.CHANNEL: p.parse_channel,
    Op.MESSAGE: p.parse_message_head,
    Op.CHUNK: p.parse_chunk,
    Op.MESSAGE_INDEX: p.parse_message_index,
    Op.CHUNK_INDEX: p.parse_chunk_index,
    Op.ATTACHMENT: p.parse_attachment,
    Op.ATTACHMENT_INDEX: p.parse_attachment_index,
    Op.STATISTICS: p.parse_statistics,
    Op.METADATA: p.parse_metadata,
    Op.METADATA_INDEX: p.parse_metadata_index,
    Op.SUMMARY_OFFSET: p.parse_summary_offset,
    Op.DATA_END: p.parse_data_end,
    Op.FOOTER: p.parse_footer,
}


def parses(buf: mmap.mmap, pos: int, limit: int) -> bool:
    """True if a whole record (not a message, whose body is free) parses exactly at ``pos``."""
    try:
        opcode, c = p.record_at(buf, pos, limit)
        if opcode in (Op.HEADER, Op.MESSAGE):
            return False
        _PARSERS[Op(opcode)](c)
    except p.BadRecordError:
        return False
    return True


def next_record(buf: mmap.mmap, start: int, limit: int) -> int | None:
    """The first offset in ``[start, limit)`` where a record parses, or None."""
    view = np.frombuffer(buf, dtype=np.uint8)
    pos = start
    while pos + RECORD_HEADER.size <= limit:
        stop = min(limit, pos + _WINDOW + RECORD_HEADER.size)
        window = view[pos:stop]
        n = len(window) - RECORD_HEADER.size + 1
        candidates = np.isin(window[:n], _OPCODES)
        for high in range(5, 9):
            candidates &= window[high : high + n] == 0
        for found in np.flatnonzero(candidates).tolist():
            if parses(buf, pos + found, limit):
                return pos + found
        pos += n
    return None
