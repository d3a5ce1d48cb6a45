"""The `.jrec` recording format: writer and reader (docs/design.md §4).

Layout (little-endian; docs/recording.md is the full description and the compatibility rules):

    magic            8 bytes  b"JREC\\r\\n\\x1a\\n" (catches text-mode and truncation damage early)
    format_version   u16      FORMAT_VERSION (2)
    metadata_length  u32      L
    metadata         L bytes  JSON, UTF-8 (rig TOML text, firmware hello, host, port, start, ...)
    guard            24 bytes b"JRECMETA" | format_version u16 | flags u16 (0) | L u32 |
                              CRC-32 of the metadata u32 | CRC-32 of the 12 bytes before it u32
    metadata copy    L bytes  the metadata again
    records ...      u32 length | u64 host_receive_time_ns | `length` bytes exactly as read

Version 1 (the first writer's) has no guard and no copy: the records follow the metadata.

A damaged header or metadata loses nothing after it. The magic is accepted up to
MAGIC_TOLERANCE_BITS flipped bits. The guard (checked by its own CRC, found where the
preamble's length puts it, else by its marker) says the version and the length when the
preamble's are damaged; the metadata's CRC picks the intact copy of the two. With neither copy
intact the records are still read (from where the guard puts them, or from the first chain of
plausible records) with no metadata: `replay --rig` supplies the rig. Each such fall-back is
named in `damage`, with its byte offsets.

A record holds whatever one read from the port returned: frames, parts of frames, garbage. So a
recording is lossless (replaying it through the decoder reproduces every count, damage included)
and the writer never needs to understand the protocol. The writer only appends and flushes every
record, so a kill at any byte leaves a valid prefix: the reader returns every complete record, the
bytes of a cut last record (their complete frames decode), and reports how much was cut.

A damaged record header is damage, not the end of the recording: the reader counts it, names
its offset in `damage`, resynchronises at the next record and keeps every good record before
and after it. A header is plausible when its length is 1..MAX_RECORD (the writer never writes
an empty record) and, where a receive time is checked, that time lies within -1 min..+7 days
of the reference; a record is confirmed when its header is plausible and it ends at the end of
the file (or within a header's size of it: a cut header) or where a plausible header with a
time near its own starts. Records are read one after the other while each is confirmed. When
one is not:
- its length is 0 or over MAX_RECORD: damaged; the reader looks for the next offset where a
  confirmed record starts, timed near the last confirmed record, and resumes there (to resume,
  the record there must be followed by RESYNC_CHAIN - 1 more plausible headers in a row, or by
  the file's end: in a recording timed from 0 one header's worth of device bytes can pass);
- it runs past the end of the file or what follows it is not a header: if a confirmed record
  starts inside it, its length is damaged and the reader resumes there; if not, a record past
  the end is a cut (as above), and one that fits is kept (what follows it is the damage).
The bytes of a damaged span are kept as received data, without the damaged header's 12 bytes
when its receive time is plausible (then only its length was hit): the decoder finds the frames
in them and counts what it cannot read. Device bytes rarely look like a header: COBS frames hold
no 0x00 but their delimiters, while a header's length and time hold several.

A file with no complete header holds nothing: `JrecReader.open` refuses it (empty, or cut
before the end of its header). A metadata length that does not fit the file (beyond its end
while a complete metadata object is there, or one that does not end where the metadata does)
is damage, not a cut: the reader finds where the metadata really ends, reads the records from
there and names the damaged offset in `damage`; with nothing readable after it, it refuses.
"""

from __future__ import annotations

import contextlib
import json
import mmap
import os
import re
import struct
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from jointangle.errors import InputError

MAGIC = b"JREC\r\n\x1a\n"
FORMAT_VERSION = 2  # what the writer writes; the reader reads every version up to it
MAGIC_TOLERANCE_BITS = 3  # flipped bits in the magic still read as a (damaged) .jrec
GUARD_MARKER = b"JRECMETA"
_PREAMBLE = struct.Struct("<8sHI")
_GUARD = struct.Struct("<8sHHIII")  # marker, version, flags, metadata length, CRCs
_META_LENGTH_OFFSET = 10  # byte offset of metadata_length in the preamble
_VERSION_OFFSET = 8
LAZY_MIN_BYTES = 1 << 20  # smaller recordings are read whole even when lazy is asked for
LAZY_BATCH = 256  # records per batch of a lazy reader
LAZY_RELEASE_BYTES = 8 << 20  # a lazy reader lets the pages it passed go every 8 MiB
MAX_METADATA = 1 << 24  # a metadata length above this is damage (the writer's are ~2 kB)
_RECORD = struct.Struct("<IQ")
MAX_RECORD = 1 << 24  # a sanity bound for one read; larger lengths mean a damaged file
# How far a record's receive time may be from the previous good record's and still count as
# plausible when resynchronising after damage: back for clock adjustments, ahead for gaps.
_NS_BACK = 60 * 10**9
_NS_AHEAD = 7 * 86_400 * 10**9
# Where a length in 1..MAX_RECORD (u32, little-endian) starts: byte 3 is 0 and another is not,
# or it is exactly MAX_RECORD. A lookahead, so that overlapping positions are all found.
_LENGTH = re.compile(rb"(?=(?:[^\x00][\s\S]{2}|\x00[^\x00][\s\S]|\x00\x00[^\x00])\x00"
                     rb"|\x00\x00\x00\x01)")


@dataclass(frozen=True, slots=True)
class Record:
    """Bytes as received and the host's receive time (ns since the Unix epoch)."""

    host_ns: int
    data: bytes


class JrecWriter:
    """Append-only writer; every record is flushed to the OS before `write` returns.

        with JrecWriter(path, {"rig": rig_text, "port": url}) as w:
            w.write(chunk)               # receive time taken now
            w.write(chunk, host_ns=t)    # or given
    `fsync_every_s` additionally forces data to disk periodically (power loss, not just a kill).
    """

    def __init__(self, path: str | Path, metadata: dict[str, Any] | None = None, *,
                 overwrite: bool = False, fsync_every_s: float = 1.0) -> None:
        self.path = Path(path)
        meta = dict(metadata or {})
        meta.setdefault("format", "jointangle recording")
        meta.setdefault("created_ns", time.time_ns())
        blob = json.dumps(meta, sort_keys=True).encode("utf-8")
        try:
            self._f: BinaryIO = open(self.path, "wb" if overwrite else "xb")  # noqa: SIM115
        except FileExistsError:
            raise InputError("recording already exists (refusing to overwrite)",
                             path=self.path) from None
        except OSError as exc:
            raise InputError(f"cannot create recording: {exc.strerror}", path=self.path) from None
        self._failed = False
        self.records = 0
        self.bytes = 0
        try:
            with self._errors():
                self._f.write(_PREAMBLE.pack(MAGIC, FORMAT_VERSION, len(blob)) + blob
                              + _guard(FORMAT_VERSION, blob) + blob)
                self._f.flush()
        except InputError:
            self.close()
            if self.path.is_file():  # a header cut short records nothing: leave no file
                self.path.unlink(missing_ok=True)
            raise
        self._fsync_every_ns = int(fsync_every_s * 1e9)
        self._last_sync = time.monotonic_ns()

    def write(self, data: bytes, host_ns: int | None = None) -> None:
        if not data or self._failed:  # after a write error (raised once) nothing more is kept
            return
        if len(data) > MAX_RECORD:
            for i in range(0, len(data), MAX_RECORD):
                self.write(data[i : i + MAX_RECORD], host_ns)
            return
        t = time.time_ns() if host_ns is None else host_ns
        with self._errors():
            # One write call per record: a kill can cut it, but never interleave two.
            self._f.write(_RECORD.pack(len(data), t) + data)
            self._f.flush()
            self.records += 1
            self.bytes += len(data)
            now = time.monotonic_ns()
            if now - self._last_sync >= self._fsync_every_ns:
                os.fsync(self._f.fileno())
                self._last_sync = now

    @contextlib.contextmanager
    def _errors(self) -> Iterator[None]:
        """A write error (disk full, the device gone) as an InputError naming the file; once
        one happened, close() only closes (the first error is the one to report)."""
        try:
            yield
        except OSError as exc:
            self._failed = True
            kept = (f" (the file is valid up to its last complete record: {self.records} "
                    "records)" if self.records else "")
            raise InputError(f"cannot write recording: {exc.strerror or exc}{kept}",
                             path=self.path) from None

    def close(self) -> None:
        if self._f.closed:
            return
        if self._failed:
            with contextlib.suppress(OSError):
                self._f.close()  # (its flush fails again: nothing more can be written)
            return
        try:
            with self._errors():
                self._f.flush()
                os.fsync(self._f.fileno())
        finally:
            with contextlib.suppress(OSError):
                self._f.close()

    def __enter__(self) -> JrecWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


@dataclass
class JrecReader:
    """A whole recording read into memory (recordings are small: ~35 kB/s at 500 frames/s).

    `records` are the complete records; `partial` is the received bytes of a record cut by a
    kill (or None); `truncated_bytes` counts bytes after the last complete record.
    `damaged_records` counts record headers found damaged (each named in `damage`; the reader
    resynchronised at the next record) and `dropped_bytes` the damaged header bytes left out of
    the received data.
    """

    path: Path
    format_version: int = FORMAT_VERSION
    metadata: dict[str, Any] = field(default_factory=dict)
    records: list[Record] = field(default_factory=list)
    partial: Record | None = None
    truncated_bytes: int = 0
    header_truncated: bool = False
    damage: list[str] = field(default_factory=list)  # what was damaged, naming byte offsets
    damaged_records: int = 0
    dropped_bytes: int = 0
    records_start: int = 0  # byte offset of the first record
    metadata_source: str = "header"  # "header", "copy" (the second copy) or "none"
    record_count: int = 0  # records read (with the cut one), once they have all been read
    # open(lazy=True): the file mapped, records read as chunks() goes (see there)
    _mapped: Any = field(default=None, repr=False, compare=False)
    _header_damage: int = field(default=0, repr=False, compare=False)

    @classmethod
    def open(cls, path: str | Path, *, lazy: bool = False) -> JrecReader:
        """Read a recording. lazy=True maps the file and reads no record yet: chunks() then
        reads them one batch at a time and lets the pages it has passed go, so a recording of
        any length takes bounded memory (replay --verify of an hour at 500 Hz). `records`
        stays empty; record_count, the damage and the cut are known once chunks() has run."""
        p = Path(path)
        try:
            if lazy and p.stat().st_size >= LAZY_MIN_BYTES:
                with open(p, "rb") as f:
                    raw: Any = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
            else:
                lazy = False
                raw = p.read_bytes()
        except OSError as exc:
            raise InputError(f"cannot read recording: {exc.strerror}", path=p) from None
        rd = cls.parse(raw, p, records=not lazy)
        if rd.header_truncated:
            raise InputError(_header_cut(raw), path=p)
        if lazy:
            rd._mapped = raw
            rd._header_damage = len(rd.damage)
        return rd

    @classmethod
    def parse(cls, raw: bytes, path: Path | str = "<recording>", *,
              records: bool = True) -> JrecReader:
        """Read a recording's bytes (records=False: only its header)."""
        rd = cls(Path(path))
        head = raw[: len(MAGIC)]
        flipped = _bit_distance(head, MAGIC[: len(head)])
        if flipped > (MAGIC_TOLERANCE_BITS if len(head) == len(MAGIC) else 0):
            raise InputError("not a .jrec recording (bad magic bytes)", path=path)
        if flipped:
            rd.damage.append(f"magic (byte offsets 0-7) is damaged ({flipped} bit(s) flipped): "
                             "read as a recording")
        if len(raw) < _PREAMBLE.size:
            rd.header_truncated = True
            rd.truncated_bytes = len(raw)
            return rd
        _, version, meta_len = _PREAMBLE.unpack_from(raw)
        if version != 1 or _read_guard(raw, _PREAMBLE.size + meta_len) is not None:
            _parse_v2(rd, raw, version, meta_len)
            if records and not rd.header_truncated:
                _read_records(rd, raw, rd.records_start)
                rd.record_count = len(rd.records) + (rd.partial is not None)
                rd._check_recoverable()
            return rd
        rd.format_version = version
        pos = _PREAMBLE.size + meta_len
        meta = _parse_metadata(raw[_PREAMBLE.size : pos]) if len(raw) >= pos else None
        if meta is None:
            found = _find_metadata(raw)
            if found is None and len(raw) < pos:
                # The bytes after the preamble are the start of the metadata: a cut.
                rd.header_truncated = True
                rd.truncated_bytes = len(raw)
                return rd
            if found is None:
                raise InputError(f"metadata (bytes {_PREAMBLE.size}-{pos}) is damaged: "
                                 f"{_metadata_error(raw[_PREAMBLE.size : pos])}", path=path,
                                 field="metadata")
            meta, end = found
            rd.damage.append(f"metadata length at byte offset {_META_LENGTH_OFFSET} is "
                             f"damaged: it says {meta_len} bytes, the metadata ends after "
                             f"{end - _PREAMBLE.size} (byte offset {end}; the file has "
                             f"{len(raw)} bytes)")
            pos = end
        rd.metadata = meta if isinstance(meta, dict) else {"value": meta}
        rd.records_start = pos
        if records:
            _read_records(rd, raw, pos)
            rd.record_count = len(rd.records) + (rd.partial is not None)
            rd._check_recoverable()
        return rd

    def _check_recoverable(self) -> None:
        if self.damage and not self.record_count:
            raise InputError(f"{self.damage[-1]}; no record follows it: nothing to recover",
                             path=self.path)

    def data(self) -> bytes:
        """Every received byte in order, the cut record's included."""
        return b"".join(r.data for r in self.chunks())

    def chunks(self) -> Iterator[Record]:
        """Every record in order, then the cut one. For a lazy reader each pass reads the
        file again, a batch of records at a time (the same records, damage and counts)."""
        if self._mapped is None:
            yield from self.records
            if self.partial is not None:
                yield self.partial
            return
        mm = self._mapped
        del self.damage[self._header_damage :]  # a new pass finds the record damage again
        self.partial, self.truncated_bytes = None, 0
        self.damaged_records = self.dropped_bytes = 0
        count = 0
        released = 0
        for pos in _scan_records(self, mm, self.records_start, batch=LAZY_BATCH):
            count += len(self.records)
            yield from self.records
            self.records.clear()
            if pos - released >= LAZY_RELEASE_BYTES:  # done with these pages
                upto = pos - pos % mmap.PAGESIZE
                mm.madvise(mmap.MADV_DONTNEED, released, upto - released)
                released = upto
        count += len(self.records)
        yield from self.records
        self.records.clear()
        if self.partial is not None:
            count += 1
            yield self.partial
        self.record_count = count
        self._check_recoverable()

    def close(self) -> None:
        """Unmap a lazy reader's file (nothing to do for one read whole)."""
        if self._mapped is not None:
            self._mapped.close()
            self._mapped = None


def _guard(version: int, blob: bytes) -> bytes:
    """The 24-byte guard between the metadata and its copy."""
    body = struct.pack("<HHII", version, 0, len(blob), zlib.crc32(blob))
    return GUARD_MARKER + body + struct.pack("<I", zlib.crc32(body))


@dataclass(frozen=True)
class _Guard:
    at: int  # byte offset
    version: int
    meta_len: int
    meta_crc: int
    marker_bits: int  # bits of the marker found flipped


def _read_guard(raw: bytes, at: int) -> _Guard | None:
    """The guard at byte offset `at` if its CRC holds (its marker may have a few bits flipped),
    else None."""
    if at < 0 or len(raw) - at < _GUARD.size:
        return None
    marker, version, _flags, meta_len, meta_crc, crc = _GUARD.unpack_from(raw, at)
    bits = _bit_distance(marker, GUARD_MARKER)
    if bits > MAGIC_TOLERANCE_BITS or zlib.crc32(raw[at + 8 : at + 20]) != crc:
        return None
    return _Guard(at, version, meta_len, meta_crc, bits)


def _search_guard(raw: bytes) -> _Guard | None:
    """The first intact guard found by its marker (when the preamble's length is damaged)."""
    at = raw.find(GUARD_MARKER, _PREAMBLE.size)
    while at >= 0:
        g = _read_guard(raw, at)
        if g is not None and at - g.meta_len == _PREAMBLE.size:
            return g
        at = raw.find(GUARD_MARKER, at + 1)
    return None


def _parse_v2(rd: JrecReader, raw: bytes, version: int, meta_len: int) -> None:
    """Header and metadata of a version-2 file (or one whose version field is damaged), each
    fall-back named in rd.damage; sets records_start (or header_truncated for a cut header)."""
    pre = _PREAMBLE.size
    n = len(raw)
    g = _read_guard(raw, pre + meta_len)
    if g is None:
        g = _search_guard(raw)
        if g is not None:
            if g.meta_len != meta_len:
                rd.damage.append(f"metadata length at byte offset {_META_LENGTH_OFFSET} is "
                                 f"damaged: it says {meta_len} bytes, the metadata guard found "
                                 f"at byte offset {g.at} says {g.meta_len}")
            meta_len = g.meta_len
    if g is None:
        if version > FORMAT_VERSION:
            raise InputError(f"recording format version {version}, this host reads up to "
                             f"version {FORMAT_VERSION}: update jointangle (no intact metadata "
                             "guard of this host's format either)", path=rd.path)
        if n < pre + 2 * meta_len + _GUARD.size and meta_len <= MAX_METADATA:
            rd.header_truncated = True  # the header was never written whole: a cut
            rd.truncated_bytes = n
            return
        rd.damage.append(f"metadata guard at byte offset {pre + meta_len} is damaged "
                         "(format version and metadata checksum unknown)")
    if g is not None:
        if g.version != version:
            rd.damage.append(f"format version at byte offset {_VERSION_OFFSET} is damaged: it "
                             f"says {version}, the metadata guard says {g.version}")
        version = g.version
        if g.marker_bits:
            rd.damage.append(f"metadata guard marker at byte offset {g.at} is damaged "
                             f"({g.marker_bits} bit(s) flipped); its checksum holds")
        if version > FORMAT_VERSION:
            raise InputError(f"recording format version {version}, this host reads up to "
                             f"version {FORMAT_VERSION}: update jointangle", path=rd.path)
    rd.format_version = version
    guard_at = pre + meta_len
    copy_at = guard_at + _GUARD.size
    rd.records_start = copy_at + meta_len
    if n < rd.records_start:
        rd.header_truncated = True
        rd.truncated_bytes = n
        return
    first, copy = raw[pre:guard_at], raw[copy_at : rd.records_start]
    if g is not None:
        first_ok, copy_ok = zlib.crc32(first) == g.meta_crc, zlib.crc32(copy) == g.meta_crc
    else:  # no checksum: the copies vouch for each other
        first_ok = copy_ok = first == copy
    meta = _parse_metadata(first) if first_ok else None
    if meta is None and copy_ok:
        meta = _parse_metadata(copy)
    where = f"bytes {pre}-{guard_at - 1}"
    copy_where = f"bytes {copy_at}-{rd.records_start - 1}"
    if isinstance(meta, dict) and first_ok:
        if not copy_ok:
            rd.damage.append(f"metadata copy ({copy_where}) is damaged; the first copy is "
                             "intact")
    elif isinstance(meta, dict):
        rd.metadata_source = "copy"
        rd.damage.append(f"metadata ({where}) is damaged: read from its second copy "
                         f"({copy_where})")
    else:
        meta = {}
        rd.metadata_source = "none"
        rd.damage.append(f"metadata ({where}) and its copy ({copy_where}) are damaged: the "
                         "records are read without it (replay --rig gives the rig; the hello "
                         "comes from the recorded frames)")
    rd.metadata = meta


def _bit_distance(a: bytes, b: bytes) -> int:
    """Bits in which two byte strings of one length differ."""
    return sum((x ^ y).bit_count() for x, y in zip(a, b, strict=True))


def _read_records(rd: JrecReader, raw: bytes, pos: int) -> None:
    """Append the records of raw[pos:] to rd, resynchronising after damaged headers."""
    for _ in _scan_records(rd, raw, pos):
        pass


def _scan_records(rd: JrecReader, raw: bytes, pos: int, batch: int = 0) -> Iterator[int]:
    """_read_records, pausing (yielding the offset reached) whenever rd.records holds `batch`
    records (0: never) so that the caller can take them out."""
    n = len(raw)
    size = _RECORD.size
    unpack = _RECORD.unpack_from
    append = rd.records.append
    last_ns: int | None = None  # receive time of the last record a neighbour confirmed
    while pos < n:
        if batch and len(rd.records) >= batch:
            yield pos
        if n - pos < size:
            rd.truncated_bytes = n - pos
            return
        length, host_ns = unpack(raw, pos)
        start = pos + size
        end = start + length
        if 0 < length <= MAX_RECORD:
            if end <= n - size:  # the common case, inline: a plausible header follows
                next_length, next_ns = unpack(raw, end)
                if (0 < next_length <= MAX_RECORD
                        and -_NS_BACK <= next_ns - host_ns <= _NS_AHEAD):
                    append(Record(host_ns, raw[start:end]))
                    last_ns, pos = host_ns, end
                    continue
            elif end <= n:  # the last record, or a cut header follows
                append(Record(host_ns, raw[start:end]))
                last_ns, pos = host_ns, end
                continue
            # Runs past the end of the file, or no record starts where it ends: a damaged
            # length if a record starts inside it.
            # A header whose time is not near the last is no header (the record before it was
            # cut short by a damaged length): a record may start right after its first byte.
            header = _near(host_ns, last_ns)
            nxt = _next_record(raw, start if header else pos + 1, min(end, n),
                               host_ns if last_ns is None else last_ns)
            if nxt is not None:
                if header:
                    last_ns = host_ns
                _damaged(rd, raw, pos, length, host_ns if header else last_ns or 0, header, nxt)
                pos = nxt
                continue
            if end > n:  # a cut last record
                rd.partial = Record(host_ns, raw[start:n])
                rd.truncated_bytes = n - pos
                return
            # The next header is damaged; this one's time counts only if it fits the last.
            rd.records.append(Record(host_ns, raw[start:end]))
            if _near(host_ns, last_ns):
                last_ns = host_ns
            pos = end
            continue
        nxt = _next_record(raw, pos + 1, n, last_ns)
        stop = n if nxt is None else nxt
        header = _near(host_ns, last_ns) and stop - pos >= _RECORD.size
        _damaged(rd, raw, pos, length, host_ns if header else last_ns or 0, header, nxt)
        pos = stop


def _damaged(rd: JrecReader, raw: bytes, pos: int, length: int, host_ns: int, header: bool,
             nxt: int | None) -> None:
    """Record the damaged header at pos and keep the bytes up to the next record (or the end)
    as received data; without the header's 12 bytes when they still look like a header."""
    stop = len(raw) if nxt is None else nxt
    begin = pos + _RECORD.size if header else pos
    if stop > begin:
        rd.records.append(Record(host_ns, raw[begin:stop]))
    rd.damaged_records += 1
    rd.dropped_bytes += begin - pos
    where = (f"resynchronised at the next record (byte offset {nxt})" if nxt is not None else
             "no record follows it")
    rd.damage.append(f"record header at byte offset {pos} is damaged (length {length}): "
                     f"{where}, its {stop - begin} bytes read as received data")


def _near(host_ns: int, ref_ns: int | None) -> bool:
    return ref_ns is None or ref_ns - _NS_BACK <= host_ns <= ref_ns + _NS_AHEAD


def _plausible(raw: bytes, pos: int, ref_ns: int | None) -> bool:
    """A record header could start at pos: its length in 1..MAX_RECORD and its receive time
    near ref_ns (None: any)."""
    if len(raw) - pos < _RECORD.size:
        return False
    length, host_ns = _RECORD.unpack_from(raw, pos)
    return 0 < length <= MAX_RECORD and _near(host_ns, ref_ns)


def _next_record(raw: bytes, lo: int, hi: int, ref_ns: int | None) -> int | None:
    """The first offset in [lo, hi) where a plausible header starts whose record ends at the
    end of the file (or within a header's size of it) or where another plausible header
    starts, or None."""
    n = len(raw)
    hi = min(hi, n - _RECORD.size + 1)
    for m in _LENGTH.finditer(raw, lo, hi + 3):  # + 3: the lookahead reads 4 bytes
        q = m.start()
        if q >= hi:
            break
        host_ns = _RECORD.unpack_from(raw, q)[1]
        if not _near(host_ns, ref_ns):
            continue
        if _chain(raw, q, host_ns, RESYNC_CHAIN):
            return q
    return None


RESYNC_CHAIN = 3  # headers in a row (or the file's end) that confirm a resynchronisation


def _chain(raw: bytes, q: int, host_ns: int, hops: int) -> bool:
    """A plausible header at q is followed by `hops - 1` more, each where the one before ends
    and timed near it, or by the file's end (within a header's size): device bytes that look
    like one header (a length and a small receive time, e.g. a recording timed from 0) rarely
    look like three in a row."""
    n = len(raw)
    for _ in range(hops):
        length = _RECORD.unpack_from(raw, q)[0]
        end = q + _RECORD.size + length
        if end > n:
            return False
        if n - end < _RECORD.size:
            return True
        if not _plausible(raw, end, host_ns):
            return False
        q, host_ns = end, _RECORD.unpack_from(raw, end)[1]
    return True


def _parse_metadata(blob: bytes) -> Any | None:
    """The metadata JSON, or None when the bytes are not one JSON value."""
    try:
        return json.loads(blob.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None


def _metadata_error(blob: bytes) -> str:
    """Why the metadata bytes do not parse, naming the byte offset in the file."""
    try:
        text = blob.decode("utf-8")
    except UnicodeDecodeError as exc:
        return f"not UTF-8 at byte offset {_PREAMBLE.size + exc.start}"
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        at = _PREAMBLE.size + len(text[: exc.pos].encode("utf-8"))
        return f"not valid JSON at byte offset {at} ({exc.msg})"
    return "not valid JSON"  # pragma: no cover


def _find_metadata(raw: bytes) -> tuple[dict[str, Any], int] | None:
    """The metadata object that starts right after the preamble and where it ends (a byte
    offset), found by parsing rather than by the length field; None if there is none."""
    # latin-1 maps bytes to characters one to one, so the decoder's index is a byte offset
    # (the writer's JSON is ASCII); the object found is then decoded again as UTF-8.
    text = raw[_PREAMBLE.size :].decode("latin-1")
    try:
        _, n = json.JSONDecoder().raw_decode(text)
    except json.JSONDecodeError:
        return None
    end = _PREAMBLE.size + n
    meta = _parse_metadata(raw[_PREAMBLE.size : end])
    return (meta, end) if isinstance(meta, dict) else None


def _header_cut(raw: bytes) -> str:
    """Why a file with no complete header is not a recording one can read."""
    if not raw:
        return ("empty file: not a jointangle recording (a .jrec starts with a "
                f"{_PREAMBLE.size}-byte header and its metadata)")
    if len(raw) < _PREAMBLE.size:
        return (f"cut short before the end of its header ({len(raw)} of {_PREAMBLE.size} "
                "bytes): nothing was recorded")
    _, version, meta_len = _PREAMBLE.unpack_from(raw)
    if version == 1:
        return (f"cut short inside its header (metadata: {len(raw) - _PREAMBLE.size} of "
                f"{meta_len} bytes): nothing was recorded")
    return (f"cut short inside its header ({len(raw)} of "
            f"{_PREAMBLE.size + 2 * meta_len + _GUARD.size} bytes: metadata, guard, copy): "
            "nothing was recorded")
