"""The session writer: MCAP (profile ``ros2``, ``cdr``, zstd chunks) fit for a 1 kHz loop.

Messages are packed with one ``struct`` call each (:mod:`.encode`) into an in-memory chunk, in
arrival order, as rosbag2 writes them. A chunk is compressed, written and flushed to the
operating system as soon as it spans ``chunk_span_s`` of log time, so a killed process loses at
most that much (0.25 s by default, 0.5 s at most: docs/recording-format.md) and ``hilrig recover``
restores the rest. Schemas, channels, metadata and attachments are written before any chunk, so
a file cut anywhere is recoverable; after a failed write (a full disk) :meth:`~SessionWriter.seal`
cuts it back to its last whole chunk. Long sessions can be split into numbered files
(:mod:`.split`).

A write costs about 2 us; closing a chunk compresses its 0.25 s of data (about 1 ms at 1 kHz
on every topic), so call the writer from a logging thread rather than from the control tick.
The writer is not thread-safe.
"""

from __future__ import annotations

import io
import os
import sys
import zlib
from array import array
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, cast

import zstandard

from hilrig import __version__
from hilrig.errors import RecordingError
from hilrig.recording import mcap_records as rec
from hilrig.recording.encode import ChannelEncoder
from hilrig.recording.msgdef import full_definition
from hilrig.recording.outcome import OUTCOME_METADATA
from hilrig.recording.samples import Sample, TextSample
from hilrig.recording.schema import (
    MESSAGE_ENCODING,
    PROFILE,
    SCHEMA_ENCODING,
    ChannelSpec,
    MessageType,
)
from hilrig.recording.session import (
    CALIBRATION_METADATA,
    SESSION_METADATA,
    SessionInfo,
    calibration_metadata,
)
from hilrig.recording.split import SplitPolicy, part_path

LIBRARY = f"hilrig/{__version__}"
ROBOT_DESCRIPTION = ChannelSpec("/robot_description", MessageType.STRING, latched=True)
_U32 = 0xFFFFFFFF


class _Channel:
    """A registered channel: its encoder, sequence counter, and the open chunk's index of it."""

    __slots__ = ("count", "counter", "device_clock", "encoder", "index", "record")

    def __init__(self, record: rec.Channel, encoder: ChannelEncoder, device_clock: bool) -> None:
        self.record = record
        self.encoder = encoder
        self.device_clock = device_clock
        self.counter = 0  # the MCAP sequence of channels without a device sequence
        self.count = 0  # messages in the current file
        self.index = array("Q")  # log time, offset pairs of the open chunk


class SessionWriter:
    """Write one session to ``path`` (or to numbered parts of it when ``split`` is given).

    ``session`` becomes the ``session`` metadata record, ``calibration`` the ``calibration``
    record; ``attachments`` (config, scenario) are stored as MCAP attachments. ``urdf`` (the
    robot model's XML) is attached as ``robot.urdf`` and published once on the latched
    ``/robot_description`` topic, where ROS tools, Foxglove and Rerun look for it. Every part
    of a split session repeats all of these. Refuses to overwrite an existing file.
    Raises RecordingError for an existing output, an unknown topic or a sample that does not fit.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        session: SessionInfo,
        *,
        channels: Iterable[ChannelSpec] = (),
        calibration: Mapping[str, object] | None = None,
        attachments: Sequence[rec.Attachment] = (),
        urdf: str | None = None,
        chunk_span_s: float = 0.25,
        max_chunk_bytes: int = 8 << 20,
        compression_level: int = 3,
        split: SplitPolicy | None = None,
    ) -> None:
        if not 0 < chunk_span_s <= 0.5:
            raise RecordingError(f"chunk_span_s must be in (0, 0.5] s, got {chunk_span_s}")
        self.path = Path(path)
        self.session = session
        self._offset_ns = session.clock_offset_ns
        self._metadata: list[rec.Metadata] = []  # after the session record, in every part
        if calibration:
            calibration_record = rec.Metadata(
                CALIBRATION_METADATA, calibration_metadata(calibration)
            )
            self._metadata.append(rec.sealed(calibration_record))
        # An empty serialized_metadata makes rosbag2 read the numeric QoS policies.
        self._metadata.append(rec.Metadata("rosbag2", {"serialized_metadata": ""}))
        self._attachments = list(attachments)
        self._urdf = urdf
        if urdf is not None:
            robot = rec.Attachment(
                "robot.urdf", "application/xml", urdf.encode(), log_time=session.start_utc_ns
            )
            self._attachments.append(robot)
        self._span_ns = round(chunk_span_s * 1e9)
        self._max_chunk_bytes = max_chunk_bytes
        # The frame checksum lets readers verify a chunk while inflating it (see chunks.py).
        self._compressor = zstandard.ZstdCompressor(level=compression_level, write_checksum=True)
        self._split = split
        self._schemas: dict[MessageType, rec.Schema] = {}
        self._channels: dict[str, _Channel] = {}
        self._file: BinaryIO | None = None
        self.paths: list[Path] = []
        self._part = 0
        # Per part (reset by _open_part): bytes written and their CRC, open chunk, indexes.
        self._pos = 0
        self._crc = 0
        self._buf = bytearray()
        self._chunk_start = self._chunk_end = 0
        self._part_start, self._part_end = 2**64 - 1, 0
        self._whole_pos = 0  # the file's bytes handed to the OS whole (ending in a record)
        self._whole_end_ns = 0  # the last log time of the whole chunks handed over (0: none)
        self._chunk_indexes: list[rec.ChunkIndex] = []
        self._metadata_indexes: list[bytes] = []
        self._attachment_indexes: list[bytes] = []
        self._open_part()
        for spec in channels:
            self.add_channel(spec)
        if urdf is not None:
            self.add_channel(ROBOT_DESCRIPTION)
            self._describe_robot(session.start_monotonic_ns)

    # -- public API -------------------------------------------------------------------------

    def add_channel(self, spec: ChannelSpec) -> None:
        """Register ``spec``'s topic. Raises RecordingError if the topic is already taken."""
        if spec.topic in self._channels:
            raise RecordingError(f"{self.path}: topic {spec.topic} is already registered")
        schema = self._schemas.get(spec.type)
        if schema is None:
            data = full_definition(spec.type.value).encode()
            schema = rec.Schema(len(self._schemas) + 1, spec.type.value, SCHEMA_ENCODING, data)
            self._schemas[spec.type] = schema
            self._write(schema.encode())
        channel_id = len(self._channels) + 1
        record = rec.sealed(
            rec.Channel(channel_id, schema.id, spec.topic, MESSAGE_ENCODING, spec.metadata)
        )
        self._channels[spec.topic] = _Channel(
            record, ChannelEncoder(channel_id, spec), spec.device_clock
        )
        self._write(record.encode())

    def write(self, topic: str, sample: Sample) -> None:
        """Record ``sample`` on ``topic``; its log time is ``sample.t_ns`` on the session clock.

        Raises RecordingError for an unknown topic, a closed writer, a sample of the wrong type
        or shape, or a device channel's sample without device time and sequence.
        """
        channel = self._channels.get(topic)
        if channel is None or self._file is None:
            raise RecordingError(f"{self.path}: cannot write to {topic} (unknown or closed)")
        log_ns = sample.t_ns + self._offset_ns
        if channel.device_clock:
            publish_ns = getattr(sample, "device_t_ns", None)
            sequence = getattr(sample, "device_seq", None)
            if publish_ns is None or sequence is None:
                channel.encoder.check(sample)  # a sample of the wrong type says so first
                raise RecordingError(f"{topic}: samples need device_t_ns and device_seq")
            sequence &= _U32
        else:
            publish_ns = log_ns
            sequence = channel.counter & _U32
            channel.counter += 1
        data = channel.encoder.encode(sample, sequence, log_ns, publish_ns)
        buf = self._buf
        if buf and (
            log_ns - self._chunk_start >= self._span_ns or len(buf) > self._max_chunk_bytes
        ):
            self.flush()
            buf = self._buf  # empty, or holding what a new part starts with
        if not buf:
            self._chunk_start = self._chunk_end = log_ns
        elif log_ns > self._chunk_end:
            self._chunk_end = log_ns
        elif log_ns < self._chunk_start:
            self._chunk_start = log_ns
        channel.index.append(log_ns)
        channel.index.append(len(buf))
        buf += data
        channel.count += 1

    def flush(self) -> None:
        """Compress and write the open chunk now and hand it to the operating system; start
        the next file if the split policy says so."""
        self._write_chunk()
        if self._file is not None and self._split_due():
            self._finish_part()
            self._part += 1
            self._open_part()
            self._describe_robot(self._chunk_end - self._offset_ns)  # each part stands alone

    def close(self, outcome: Mapping[str, str] | None = None) -> None:
        """Write what is buffered, then ``outcome`` (the session's end figures, the metadata
        record ``outcome``, :mod:`.outcome`) if given, and the summary; the file is then
        complete. Idempotent."""
        if self._file is not None:
            self._write_chunk()
            if outcome is not None:
                self._write_metadata(rec.sealed(rec.Metadata(OUTCOME_METADATA, dict(outcome))))
            self._finish_part()

    def seal(self) -> None:
        """After a failed write (a full disk): cut the file back to its last whole chunk and close
        it, writing nothing more (no summary: ``hilrig recover`` makes it whole). Idempotent."""
        file, self._file, self._buf = self._file, None, bytearray()
        if file is None:
            return
        try:
            os.ftruncate(file.fileno(), self._whole_pos)  # frees space: needs none
        finally:
            cast(io.BufferedWriter, file).raw.close()  # closed under the buffer: no flush

    @property
    def kept_until_ns(self) -> int:
        """The last log time, on the session's clock, of the chunks handed to the OS whole (0
        if none was): what :meth:`seal` keeps."""
        return self._whole_end_ns - self._offset_ns if self._whole_end_ns else 0

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- chunks and parts -------------------------------------------------------------------

    def _write_chunk(self) -> None:
        if not self._buf or self._file is None:
            return
        data = self._buf
        compressed = self._compressor.compress(data)
        chunk_offset = self._pos
        self._write(
            rec.chunk_head(
                start_ns=self._chunk_start,
                end_ns=self._chunk_end,
                uncompressed_size=len(data),
                uncompressed_crc=zlib.crc32(data),
                compression="zstd",
                compressed_size=len(compressed),
            )
        )
        self._write(compressed)
        chunk_length = self._pos - chunk_offset
        index_offsets: dict[int, int] = {}
        index_start = self._pos
        for channel in self._channels.values():
            if channel.index:
                if sys.byteorder == "big":  # MCAP is little-endian
                    channel.index.byteswap()
                index_offsets[channel.record.id] = self._pos
                self._write(rec.message_index(channel.record.id, channel.index.tobytes()))
                channel.index = array("Q")
        self._chunk_indexes.append(
            rec.ChunkIndex(
                self._chunk_start,
                self._chunk_end,
                chunk_offset,
                chunk_length,
                index_offsets,
                self._pos - index_start,
                "zstd",
                len(compressed),
                len(data),
            )
        )
        self._part_start = min(self._part_start, self._chunk_start)
        self._part_end = max(self._part_end, self._chunk_end)
        self._buf = bytearray()
        self._file.flush()
        self._whole_pos, self._whole_end_ns = self._pos, max(self._whole_end_ns, self._chunk_end)

    def _describe_robot(self, t_ns: int) -> None:
        """Publish the URDF on /robot_description (at monotonic time ``t_ns``), if there is one."""
        if self._urdf is not None:
            self.write(ROBOT_DESCRIPTION.topic, TextSample(t_ns, self._urdf))

    def _split_due(self) -> bool:
        policy = self._split
        if policy is None:
            return False
        duration_s = (self._part_end - self._part_start) / 1e9
        too_long = policy.max_duration_s is not None and duration_s >= policy.max_duration_s
        too_big = policy.max_bytes is not None and self._pos >= policy.max_bytes
        return too_long or too_big

    def _open_part(self) -> None:
        path = self.path if self._split is None else part_path(self.path, self._part)
        try:
            self._file = path.open("xb")
        except FileExistsError as err:
            raise RecordingError(f"{path}: already exists; refusing to overwrite it") from err
        except OSError as err:
            raise RecordingError(f"{path}: cannot create ({err.strerror})") from err
        self.paths.append(path)
        self._pos = 0
        self._crc = 0
        self._buf = bytearray()
        for channel in self._channels.values():
            channel.count = 0
        self._part_start, self._part_end = 2**64 - 1, 0
        self._chunk_indexes = []
        self._metadata_indexes = []
        self._attachment_indexes = []
        self._write(rec.MAGIC + rec.header(PROFILE, LIBRARY))
        for schema in self._schemas.values():
            self._write(schema.encode())
        for channel in self._channels.values():
            self._write(channel.record.encode())
        session = rec.sealed(
            rec.Metadata(SESSION_METADATA, self.session.to_metadata(part=self._part))
        )
        for metadata in [session, *self._metadata]:
            self._write_metadata(metadata)
        for attachment in self._attachments:
            offset = self._pos
            self._write(attachment.encode())
            self._attachment_indexes.append(
                rec.attachment_index(
                    offset,
                    self._pos - offset,
                    name=attachment.name,
                    media_type=attachment.media_type,
                    log_time=attachment.log_time,
                    create_time=attachment.create_time,
                    data_size=len(attachment.data),
                )
            )
        assert self._file is not None
        self._file.flush()
        self._whole_pos = self._pos

    def _finish_part(self) -> None:
        assert self._file is not None
        counts = {c.record.id: c.count for c in self._channels.values()}
        statistics = rec.Statistics(
            message_count=sum(counts.values()),
            schema_count=len(self._schemas),
            channel_count=len(self._channels),
            attachment_count=len(self._attachments),
            metadata_count=len(self._metadata_indexes),
            chunk_count=len(self._chunk_indexes),
            message_start_time=self._part_start if any(counts.values()) else 0,
            message_end_time=self._part_end if any(counts.values()) else 0,
            channel_message_counts=counts,
        )
        self._write(
            rec.data_end_and_summary(
                self._pos,
                schemas=list(self._schemas.values()),
                channels=[c.record for c in self._channels.values()],
                statistics=statistics,
                chunk_indexes=self._chunk_indexes,
                attachment_indexes=self._attachment_indexes,
                metadata_indexes=self._metadata_indexes,
                data_crc=self._crc,
            )
        )
        self._file.close()
        self._file = None

    def _write_metadata(self, metadata: rec.Metadata) -> None:
        """Write ``metadata`` and index it."""
        offset = self._pos
        self._write(metadata.encode())
        self._metadata_indexes.append(rec.metadata_index(offset, self._pos - offset, metadata.name))

    def _write(self, data: bytes | bytearray) -> None:
        assert self._file is not None
        self._file.write(data)
        self._pos += len(data)
        self._crc = zlib.crc32(data, self._crc)  # the data section's, in its DataEnd record
