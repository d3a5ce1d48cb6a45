"""Vectorised numpy decoder for recorded byte streams (the bulk path).

Gives exactly the frames and damage counts of `framing.StreamDecoder` on any input, corrupted
included (tests/protocol/test_properties.py checks it differentially); it checks every CRC. How:

1. Cut the stream at every 0x00 (np.flatnonzero) into chunks; classify by length (empty,
   oversize, too short).
2. Group the remaining chunks by length L and handle each group as an (n, L) uint8 matrix:
   - COBS: walk the code-byte chain of all chunks at once (one numpy step per code byte, rows
     that finished drop out), zeroing the decoded positions; rows whose chain does not land
     exactly on L are malformed.
   - CRC-16/CCITT-FALSE: Horner's rule two bytes at a time with a 65536-entry table
     (T16[x] = the register after shifting two zero bytes into x), one gather per column pair.
3. Version check and hello schema checks on the accepted frames in stream order, and the
   sequence accounting of `sequence.track_bulk` (vectorised over frames in order; only the
   frames around duplicates, reordering, stale frames and restarts go one by one).

`columns(name)` then unpacks one message type into numpy columns with a structured dtype
(i24 fields are sign-extended by hand).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from jointangle.protocol.codec import SPECS_BY_NAME
from jointangle.protocol.framing import (
    CRC_INIT,
    CRC_SIZE,
    HEADER_SIZE,
    KNOWN_IDS,
    MAX_ENCODED,
    MIN_BODY,
    WHITEN,
    DecoderStats,
    Frame,
    merge_versions,
    schema_message,
    version_message,
)
from jointangle.protocol.messages import PROTOCOL_VERSION, SCHEMA_HASH, Hello
from jointangle.protocol.sequence import track_bulk
from jointangle.protocol.spec import FieldSpec, MessageSpec

U8 = npt.NDArray[np.uint8]
IntArray = npt.NDArray[np.int64]


def crc_tables() -> tuple[npt.NDArray[np.uint16], npt.NDArray[np.uint16]]:
    """(T8, T16s) for CRC-16/CCITT-FALSE (poly 0x1021).

    T8 is the usual byte table. T16s processes two bytes at once on *byte-swapped* registers:
    with T16[x] = the register after shifting two zero bytes into x, feeding the big-endian word
    w is r -> T16[r ^ w]. Reading the bytes as native little-endian words gives bswap(w), so we
    keep the register byte-swapped too and use T16s[x] = bswap(T16[bswap(x)]): no conversions.
    """
    reg = np.arange(256, dtype=np.uint32) << 8
    for _ in range(8):
        reg = np.where(reg & 0x8000, (reg << 1) ^ 0x1021, reg << 1) & 0xFFFF
    t8 = reg.astype(np.uint16)
    x = np.arange(65536, dtype=np.uint32)
    y = ((x << 8) & 0xFFFF) ^ t8[x >> 8]
    t16 = (((y << 8) & 0xFFFF) ^ t8[y >> 8]).astype(np.uint16)
    t16s = t16[x.astype(np.uint16).byteswap()].byteswap()
    return t8, t16s


def crc16_rows(body: U8, t8: npt.NDArray[np.uint16],
               t16s: npt.NDArray[np.uint16]) -> npt.NDArray[np.uint16]:
    """CRC of every row of an (n, m) uint8 matrix (tables from crc_tables())."""
    n, m = body.shape
    crc = np.full(n, CRC_INIT, dtype=np.uint16)
    start = 0
    if m % 2:
        crc = ((crc << 8) ^ t8[(crc >> 8) ^ body[:, 0]]).astype(np.uint16)
        start = 1
    if m > start:
        words = np.ascontiguousarray(body[:, start:]).view("<u2")  # byte-swapped words
        if words.dtype.byteorder not in ("=", "|") and not np.little_endian:  # pragma: no cover
            words = words.byteswap()
        reg = crc.byteswap()
        tmp = np.empty_like(reg)
        for k in range(words.shape[1]):
            np.bitwise_xor(reg, words[:, k], out=tmp)
            t16s.take(tmp, out=reg)
        crc = reg.byteswap()
    return crc


@dataclass
class _Group:
    """Accepted frames whose bodies share one length: chunk indices and decoded bodies."""

    chunk_index: IntArray
    body: U8
    pos: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))  # among accepted frames


@dataclass
class BulkResult:
    """Accepted frames in stream order, the damage counts and the decoded bodies by length."""

    msg_id: npt.NDArray[np.uint8]
    seq: npt.NDArray[np.uint16]
    t_us: npt.NDArray[np.uint32]
    stats: DecoderStats
    pending_bytes: int
    mismatch: str | None = None
    _groups: list[_Group] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.msg_id.size)

    def frames(self) -> list[Frame]:
        """Every accepted frame as a framing.Frame (slow: for tests and small logs)."""
        out: list[tuple[int, Frame]] = []
        for g in self._groups:
            for ci, row in zip(g.chunk_index.tolist(), g.body, strict=True):
                b = row.tobytes()
                out.append((ci, Frame(b[1], int.from_bytes(b[2:4], "little"),
                                      int.from_bytes(b[4:8], "little"),
                                      b[HEADER_SIZE:-CRC_SIZE])))
        out.sort(key=lambda p: p[0])
        return [f for _, f in out]

    def payloads(self, msg_id: int) -> Iterator[tuple[IntArray, U8]]:
        """(positions in stream order, payload matrix) per payload length, for one message id."""
        for pos, body in self._bodies(msg_id):
            yield pos, body[:, HEADER_SIZE:-CRC_SIZE]

    def _bodies(self, msg_id: int) -> Iterator[tuple[IntArray, U8]]:
        """(positions, whole decoded bodies) per body length, for one message id."""
        for g in self._groups:
            sel = np.flatnonzero(g.body[:, 1] == msg_id)
            if sel.size == g.body.shape[0]:
                yield g.pos, g.body
            elif sel.size:
                yield g.pos[sel], g.body[sel]

    def columns(self, name: str, items: int | None = None) -> dict[str, np.ndarray]:
        """Decode every frame of message `name` with one layout into numpy columns.

        Columns: 'seq', 't_us', 'index' (position among accepted frames) and one per field, raw
        integers as on the wire (char[N] as (n, N) uint8); group fields are (n, items) arrays
        named 'sensors.x'. For messages with a group, `items` picks the item count (default: the
        most common one); frames of other lengths are left out.
        """
        spec = SPECS_BY_NAME[name]
        blocks = list(self._bodies(spec.msg_id))
        want = _payload_length(spec, [(p, b[:, HEADER_SIZE:-CRC_SIZE]) for p, b in blocks], items)
        # Bodies of one length all sit in one group, already in stream order.
        found = [(p, b) for p, b in blocks if b.shape[1] == want + HEADER_SIZE + CRC_SIZE]
        pos, body = found[0] if found else (np.zeros(0, np.int64),
                                            np.zeros((0, max(want, 0) + MIN_BODY), np.uint8))
        cols: dict[str, np.ndarray] = {"index": pos, "seq": self.seq[pos], "t_us": self.t_us[pos]}
        if want < 0:
            return cols
        cols.update(_unpack(spec, body))
        return cols


def unpack_payloads(name: str, payloads: U8) -> dict[str, np.ndarray]:
    """Columns (as BulkResult.columns gives them, without index/seq/t_us) of an (n, L) matrix
    of payloads of message `name`, all of one length L (e.g. collected by a streaming pass)."""
    n, m = payloads.shape
    body = np.zeros((n, m + MIN_BODY), dtype=np.uint8)
    body[:, HEADER_SIZE : HEADER_SIZE + m] = payloads
    return _unpack(SPECS_BY_NAME[name], body)


def _payload_length(spec: MessageSpec, blocks: list[tuple[IntArray, U8]],
                    items: int | None) -> int:
    g = spec.group
    if g is None:
        return spec.fixed_size if spec.text is None else -1
    if items is not None:
        return spec.payload_size(items)
    best, best_n = -1, 0
    for _, pl in blocks:
        m = pl.shape[1]
        if (m - spec.fixed_size - 1) % g.item_size == 0 and m > spec.fixed_size and \
                pl.shape[0] > best_n:
            best, best_n = m, pl.shape[0]
    return best


def _field_dtype(f: FieldSpec, offset: int) -> tuple[object, int]:
    """numpy format and offset of a field. An i24 is read as the little-endian int32 that ends
    with it (starting one byte earlier, always inside the body) and shifted right by 8 later:
    that sign-extends it in one step."""
    if f.type == "i24":
        return "<i4", offset - 1
    fmt = {"u8": "u1", "i8": "i1", "u16": "<u2", "i16": "<i2", "u32": "<u4", "i32": "<i4",
           "f32": "<f4"}.get(f.type, ("u1", (f.size,)))  # char[N]: (n, N) uint8
    return fmt, offset


def _unpack(spec: MessageSpec, body: U8) -> dict[str, np.ndarray]:
    """Columns of n whole decoded bodies of one length, via one structured view (no copies
    besides the columns themselves)."""
    n, m = body.shape
    if m == MIN_BODY:
        return {}
    names: list[str] = []
    formats: list[object] = []
    offsets: list[int] = []
    off = HEADER_SIZE
    for f in spec.fixed_fields:
        fmt, o = _field_dtype(f, off)
        names.append(f.name)
        formats.append(fmt)
        offsets.append(o)
        off += f.size
    g = spec.group
    if g is not None:
        count = (m - MIN_BODY - spec.fixed_size - 1) // g.item_size
        item_off = off + 1
        for k in range(count):
            ioff = item_off + k * g.item_size
            for f in g.fields:
                fmt, o = _field_dtype(f, ioff)
                names.append(f"{g.name}.{k}.{f.name}")
                formats.append(fmt)
                offsets.append(o)
                ioff += f.size
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": m})
    rec = np.ascontiguousarray(body).view(dt).reshape(n)
    cols: dict[str, np.ndarray] = {}
    for f in spec.fixed_fields:
        cols[f.name] = rec[f.name] >> 8 if f.type == "i24" else rec[f.name].copy()
    if g is not None:
        for f in g.fields:
            parts = [rec[f"{g.name}.{k}.{f.name}"] for k in range(count)]
            col = np.stack(parts, axis=1) if parts else np.zeros((n, 0), np.int64)
            cols[f"{g.name}.{f.name}"] = col >> 8 if f.type == "i24" else col
    return cols


def _cobs_walk(a: U8, starts: IntArray, ends: IntArray) -> tuple[U8, npt.NDArray[np.bool_]]:
    """Walk the COBS code chains of many chunks of `a` at once.

    Returns a copy of `a` in which every code byte after a chunk's first is replaced by the
    zero it stands for and everything is unwhitened (XOR 0x55), and which chunks are valid COBS
    (their chain lands exactly on the chunk end). Codes of 0xFF (which suppress that zero) only
    occur in chunks longer than 254 bytes, which are oversize here, so every code byte that
    lands inside a chunk is a zero.
    """
    work = a.copy()
    ok = np.zeros(starts.size, dtype=bool)
    rows = np.arange(starts.size)
    pos = starts
    end = ends
    while rows.size:
        nxt = pos + a.take(pos)
        ok[rows[nxt == end]] = True
        inside = nxt < end
        rows, pos, end = rows[inside], nxt[inside], end[inside]
        work[pos] = 0
    np.bitwise_xor(work, WHITEN, out=work)  # unwhiten: the zeros put back become 0x55
    return work, ok


def bulk_decode(data: bytes | bytearray | memoryview | U8) -> BulkResult:
    """Decode a complete byte stream; a trailing chunk without delimiter is left pending."""
    a = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data
    stats = DecoderStats()
    zeros = np.flatnonzero(a == 0)
    pending = int(a.size - (zeros[-1] + 1)) if zeros.size else int(a.size)
    starts = np.empty(zeros.size, dtype=np.int64)
    if zeros.size:
        starts[0] = 0
        starts[1:] = zeros[:-1] + 1
    lengths = zeros - starts
    over = lengths > MAX_ENCODED
    stats.oversize = int(over.sum())
    skipped = int(lengths[over].sum())
    short = (lengths > 0) & (lengths < MIN_BODY + 1)
    stats.malformed = int(short.sum())
    skipped += int(lengths[short].sum())

    cand = np.flatnonzero((lengths >= MIN_BODY + 1) & ~over)
    work, cobs_ok = _cobs_walk(a, starts[cand], starts[cand] + lengths[cand])
    bad = cand[~cobs_ok]
    stats.malformed += int(bad.size)
    skipped += int(lengths[bad].sum())
    cand = cand[cobs_ok]

    t8, t16s = crc_tables()
    groups: list[_Group] = []
    mismatches: list[tuple[int, str]] = []  # (chunk index, message) of refused frames
    cand_len = lengths[cand]
    order = np.argsort(cand_len, kind="stable")
    cand, cand_len = cand[order], cand_len[order]
    bounds = np.flatnonzero(np.diff(cand_len)) + 1
    for idx in np.split(cand, bounds):
        if not idx.size:
            continue
        length = int(lengths[idx[0]])
        m = length - 1  # decoded body length
        body = np.lib.stride_tricks.sliding_window_view(work, m)[starts[idx] + 1]
        crc = crc16_rows(body[:, : m - CRC_SIZE], t8, t16s)
        stored = np.ascontiguousarray(body[:, m - CRC_SIZE :]).view("<u2").reshape(-1)
        bad = np.flatnonzero(crc != stored)
        if bad.size:
            stats.crc_errors += int(bad.size)
            skipped += length * int(bad.size)
            keep = np.flatnonzero(crc == stored)
            body, idx = body[keep], idx[keep]
        per_version = np.bincount(body[:, 0], minlength=256)
        merge_versions(stats.versions_seen,
                       {int(v): int(per_version[v]) for v in np.flatnonzero(per_version)})
        other = np.flatnonzero(body[:, 0] != PROTOCOL_VERSION)
        if other.size:
            stats.version_errors += int(other.size)
            skipped += length * int(other.size)
            mismatches.append((int(idx[other[0]]), version_message(int(body[other[0], 0]))))
            keep = np.flatnonzero(body[:, 0] == PROTOCOL_VERSION)
            body, idx = body[keep], idx[keep]
        groups.append(_Group(idx, body))

    stats.bytes_skipped = skipped
    all_idx = np.concatenate([g.chunk_index for g in groups]) if groups else np.zeros(0, np.int64)
    order_sorted = np.sort(all_idx)
    n = order_sorted.size
    msg_id = np.zeros(n, np.uint8)
    seq = np.zeros(n, np.uint16)
    t_us = np.zeros(n, np.uint32)
    for g in groups:
        pos = np.searchsorted(order_sorted, g.chunk_index)
        g.pos = pos
        head = np.ascontiguousarray(g.body[:, :HEADER_SIZE])
        msg_id[pos] = head[:, 1]
        seq[pos] = head[:, 2:4].copy().view("<u2").reshape(-1)
        t_us[pos] = head[:, 4:8].copy().view("<u4").reshape(-1)
    known = np.zeros(256, dtype=bool)  # message id -> known to this host
    known[sorted(KNOWN_IDS)] = True
    stats.unknown_messages = int(np.count_nonzero(~known[msg_id]))
    delivered = track_bulk(seq, (msg_id == Hello.MSG_ID) & (seq == 0), stats)
    if not delivered.all():  # duplicates and stale frames are not delivered
        new_pos = np.cumsum(delivered) - 1
        for g in groups:
            sel = delivered[g.pos]
            g.chunk_index, g.body, g.pos = g.chunk_index[sel], g.body[sel], new_pos[g.pos[sel]]
        msg_id, seq, t_us = msg_id[delivered], seq[delivered], t_us[delivered]
    stats.frames = int(msg_id.size)
    result = BulkResult(msg_id, seq, t_us, stats, pending, None, groups)
    mismatches += _schema_mismatches(stats, groups)
    if mismatches:
        result.mismatch = min(mismatches)[1]
    return result


def _schema_mismatches(stats: DecoderStats, groups: list[_Group]) -> list[tuple[int, str]]:
    """Count hellos announcing another schema hash; (chunk index, message) of each group's first."""
    found: list[tuple[int, str]] = []
    for g in groups:
        b = g.body
        if b.shape[1] - MIN_BODY < 5:
            continue
        hello = b[:, 1] == Hello.MSG_ID
        if not hello.any():
            continue
        h = b[hello]
        theirs = (h[:, 9].astype(np.uint32) | (h[:, 10].astype(np.uint32) << 8)
                  | (h[:, 11].astype(np.uint32) << 16) | (h[:, 12].astype(np.uint32) << 24))
        bad = theirs != SCHEMA_HASH
        stats.schema_errors += int(bad.sum())
        if bad.any():
            found.append((int(g.chunk_index[hello][bad][0]), schema_message(int(theirs[bad][0]))))
    return found
