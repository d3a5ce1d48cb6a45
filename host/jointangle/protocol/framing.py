"""Framing of the jointangle wire protocol: COBS, CRC-16 and the streaming decoder.

Hand-written twin of firmware/protocol/frame.{hpp,cpp}; both are checked against the golden
vectors in protocol/vectors/. A frame on the wire is

    COBS(whiten(version:u8 | msg_id:u8 | seq:u16 | t_us:u32 | payload | crc:u16)) | 0x00

little-endian, crc = CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR;
`binascii.crc_hqx(data, 0xFFFF)`) over everything before it; whiten = XOR every byte with 0x55
(small integers are full of 0x00 bytes, each of which would become a COBS code byte; whitened,
a frame has ~1 code byte instead of ~20, which keeps the bulk decoder's chain walk short). A body
is at most 250 bytes, so the COBS encoding is always exactly one byte longer than the body.

Damage accounting (identical in the streaming, bulk and C++ decoders): the stream is cut at every
0x00 into chunks. Empty chunks are ignored. A chunk longer than MAX_ENCODED is *oversize*; one that
is not valid COBS or decodes to fewer than 10 bytes is *malformed*; one whose CRC does not match is
a *crc error*; one with a good CRC but another protocol version is a *version error*: counted
(with the version byte, in `versions_seen`) and skipped, never fatal -- CRC-16 lets about one
damaged frame in 65 536 through, and most of those carry a wrong version byte. Only a handshake
answered in another version is refused (`link.Link.handshake`). A frame of our version with a
message id this host does not know is accepted (its sequence number counts) and also counted as
*unknown_messages*. Every rejected chunk adds its length to *bytes_skipped*.

Sequence accounting (`sequence.SequenceTracker`, serial-number arithmetic with a window):
*frames_lost* counts sequence numbers that never arrived; *duplicates* and *stale* frames are
counted and dropped; *out_of_order* frames are counted and delivered late; *segments* counts the
runs of one device boot (a hello with seq 0, or a jump back outside the window that the next
frame continues, starts a new one).
*frames* counts the frames delivered.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field
from typing import Any

from jointangle.errors import InputError
from jointangle.protocol.messages import MAX_PAYLOAD, PROTOCOL_VERSION, SCHEMA_HASH, SPECS, Hello
from jointangle.protocol.sequence import SequenceTracker

HEADER_SIZE = 8
CRC_SIZE = 2
MIN_BODY = HEADER_SIZE + CRC_SIZE
MAX_BODY = HEADER_SIZE + MAX_PAYLOAD + CRC_SIZE  # 250
MAX_ENCODED = MAX_BODY + 1  # the longest chunk between delimiters that can be a frame
MAX_FRAME_BYTES = MAX_ENCODED + 1  # with the delimiter
CRC_INIT = 0xFFFF
WHITEN = 0x55  # XORed into every body byte before COBS
_WHITEN_TABLE = bytes(i ^ WHITEN for i in range(256))  # for bytes.translate (its own inverse)

KNOWN_IDS = frozenset(s.msg_id for s in SPECS)  # message ids of this protocol's schema
_HEADER = struct.Struct("<BBHI")
_CRC = struct.Struct("<H")


class ProtocolMismatchError(InputError):
    """The other side speaks another protocol version or was built from another schema."""


def crc16(data: bytes | bytearray | memoryview, crc: int = CRC_INIT) -> int:
    """CRC-16/CCITT-FALSE; crc16(b"123456789") == 0x29B1."""
    return binascii.crc_hqx(data, crc)


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode `data` (no delimiter). Works for any length (254-byte blocks included)."""
    out = bytearray()
    out.append(0)  # placeholder code byte
    code_at = 0
    for b in data:
        if b == 0:
            out[code_at] = len(out) - code_at
            code_at = len(out)
            out.append(0)
        else:
            out.append(b)
            if len(out) - code_at == 0xFF:
                out[code_at] = 0xFF
                code_at = len(out)
                out.append(0)
    out[code_at] = len(out) - code_at
    return bytes(out)


def cobs_decode(chunk: bytes | memoryview) -> bytes | None:
    """Decode one COBS chunk (no delimiter); None if it is not valid COBS."""
    n = len(chunk)
    out = bytearray()
    i = 0
    while i < n:
        code = chunk[i]
        if code == 0:
            return None
        end = i + code
        if end > n:
            return None
        out += chunk[i + 1 : end]
        i = end
        if i < n and code != 0xFF:
            out.append(0)
    return bytes(out)


def encode_frame(msg_id: int, seq: int, t_us: int, payload: bytes, *,
                 version: int = PROTOCOL_VERSION) -> bytes:
    """One complete frame, delimiter included."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = _HEADER.pack(version, msg_id, seq & 0xFFFF, t_us & 0xFFFFFFFF) + payload
    body += _CRC.pack(crc16(body))
    return cobs_encode(body.translate(_WHITEN_TABLE)) + b"\x00"


def unwhiten(data: bytes) -> bytes:
    """Undo (or apply: it is its own inverse) the 0x55 whitening of a frame body."""
    return data.translate(_WHITEN_TABLE)


@dataclass(frozen=True, slots=True)
class Frame:
    """An accepted frame: header fields and the raw payload."""

    msg_id: int
    seq: int
    t_us: int
    payload: bytes


COUNT_KEYS = ("frames", "crc_errors", "malformed", "oversize", "version_errors",
              "schema_errors", "unknown_messages", "frames_lost", "bytes_skipped",
              "duplicates", "out_of_order", "stale", "segments")


@dataclass
class DecoderStats:
    """Damage and traffic counters (see the module docstring for the exact meaning)."""

    frames: int = 0
    crc_errors: int = 0
    malformed: int = 0
    oversize: int = 0
    version_errors: int = 0
    schema_errors: int = 0  # hellos announcing another schema hash
    unknown_messages: int = 0  # accepted frames whose message id this host does not know
    frames_lost: int = 0  # sequence numbers that never arrived
    bytes_skipped: int = 0
    duplicates: int = 0  # frames that arrived again (dropped)
    out_of_order: int = 0  # frames that arrived late, within the window (delivered)
    stale: int = 0  # frames from before the window (dropped)
    segments: int = 0  # runs of consecutive numbering (device restarts start new ones)
    # Frames with a good CRC per protocol version byte (ours included).
    versions_seen: dict[int, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, int]:
        return {k: int(getattr(self, k)) for k in COUNT_KEYS}

    def versions_json(self) -> dict[str, int]:
        """`versions_seen` with string keys, in order (for JSON)."""
        return {str(v): n for v, n in sorted(self.versions_seen.items())}


def merge_versions(into: dict[int, int], other: dict[int, int]) -> None:
    """Add the per-version frame counts of `other` to `into`."""
    for v, n in other.items():
        into[v] = into.get(v, 0) + n


def version_message(theirs: int) -> str:
    return (f"device speaks protocol version {theirs}, this host speaks version "
            f"{PROTOCOL_VERSION}: update the {'host' if theirs > PROTOCOL_VERSION else 'firmware'}")


def schema_message(theirs: int) -> str:
    return (f"device was built with protocol schema 0x{theirs:08X}, this host with "
            f"0x{SCHEMA_HASH:08X}: rebuild both from the same protocol/messages.toml")


@dataclass
class StreamDecoder:
    """Feed bytes as they arrive, get accepted frames back; never raises on damage.

    The partial chunk between calls is bounded: past MAX_ENCODED bytes only its length is kept.
    A frame of another protocol version is counted and skipped, never raised: `mismatch` holds
    the first such message and `other_hello` the version of the last hello-like frame of another
    version (what `Link.handshake` refuses). With `strict=True` a hello of our version carrying
    another schema hash raises ProtocolMismatchError naming both; otherwise it is counted.
    """

    strict: bool = False
    stats: DecoderStats = field(default_factory=DecoderStats)
    mismatch: str | None = None
    other_hello: int | None = None  # version byte of the last hello of another version
    _pending: bytearray = field(default_factory=bytearray)
    _pending_len: int = 0  # length of the current chunk, including bytes not kept (oversize)
    sequence: SequenceTracker[Frame] = field(default_factory=SequenceTracker)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        frames: list[Frame] = []
        parts = bytes(data).split(b"\x00")
        tail = parts.pop()  # bytes after the last delimiter (all of `data` if there is none)
        if parts:
            # The first part completes the chunk left over from earlier calls.
            total = self._pending_len + len(parts[0])
            chunk = bytes(self._pending) + parts[0] if total <= MAX_ENCODED else None
            self._chunk(chunk, total, frames)
            for part in parts[1:]:
                self._chunk(part, len(part), frames)
            self._pending.clear()
            self._pending_len = 0
        self._pending_len += len(tail)
        if self._pending_len <= MAX_ENCODED:
            self._pending += tail
        else:
            self._pending.clear()  # oversize: only its length matters now
        return frames

    @property
    def last_seq(self) -> int | None:
        """Newest sequence number of the current segment (None before the first frame)."""
        return self.sequence.last_seq

    def continue_after(self, previous: StreamDecoder) -> None:
        """Go on with `previous`'s sequence accounting: a decoder on a new connection to the
        same device (a reconnect) then counts the frames sent while the link was down, as one
        decoder over the whole recording does."""
        self.sequence = previous.sequence

    def finish(self) -> None:
        """The input ended: settle a frame still held by the sequence accounting (stale)."""
        self.sequence.finish(self.stats)

    @property
    def pending_bytes(self) -> int:
        """Bytes of an unfinished chunk (no delimiter yet)."""
        return self._pending_len

    def _chunk(self, chunk: bytes | None, n: int, frames: list[Frame]) -> None:
        st = self.stats
        if n == 0:
            return
        if chunk is None or n > MAX_ENCODED:
            st.oversize += 1
            st.bytes_skipped += n
            return
        body = cobs_decode(chunk)
        if body is not None:
            body = body.translate(_WHITEN_TABLE)
        if body is None or len(body) < MIN_BODY:
            st.malformed += 1
            st.bytes_skipped += n
            return
        if crc16(body[:-CRC_SIZE]) != _CRC.unpack_from(body, len(body) - CRC_SIZE)[0]:
            st.crc_errors += 1
            st.bytes_skipped += n
            return
        version, msg_id, seq, t_us = _HEADER.unpack_from(body)
        seen = st.versions_seen
        seen[version] = seen.get(version, 0) + 1
        if version != PROTOCOL_VERSION:
            st.version_errors += 1
            st.bytes_skipped += n
            if self.mismatch is None:
                self.mismatch = version_message(version)
            if msg_id == Hello.MSG_ID:
                self.other_hello = version
            return
        if msg_id not in KNOWN_IDS:
            st.unknown_messages += 1
        payload = body[HEADER_SIZE:-CRC_SIZE]
        if msg_id == Hello.MSG_ID and len(payload) >= 5:
            theirs = int.from_bytes(payload[1:5], "little")
            if theirs != SCHEMA_HASH:
                st.schema_errors += 1
                self._refuse(schema_message(theirs))
        before = len(frames)
        self.sequence.accept(seq, msg_id == Hello.MSG_ID and seq == 0,
                             Frame(msg_id, seq, t_us, payload), st, frames)
        st.frames += len(frames) - before

    def _refuse(self, message: str) -> None:
        if self.mismatch is None:
            self.mismatch = message
        if self.strict:
            raise ProtocolMismatchError(message)


def decode_stream(data: bytes, *, strict: bool = False) -> tuple[list[Frame], DecoderStats]:
    """Decode a complete byte stream (a trailing unfinished chunk is left pending, not counted;
    a frame the sequence accounting still holds at the end is stale)."""
    dec = StreamDecoder(strict=strict)
    frames = dec.feed(data)
    dec.finish()
    return frames, dec.stats


def frame_summary(frames: list[Frame]) -> list[tuple[Any, ...]]:
    """Frames as plain tuples (for comparisons in tests and tools)."""
    return [(f.msg_id, f.seq, f.t_us, f.payload) for f in frames]
