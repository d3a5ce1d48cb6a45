"""Damaged `.jrec` record headers: counted, resynchronised at the next record, nothing good lost.

A damaged record length used to end the recording there: a huge one (or zeroed bytes over a
header) refused the whole file ("record of N bytes at offset M: the file is damaged", exit 2),
and a large one within MAX_RECORD read the rest of the file as one cut record (about half the
frames lost, reported as a cut).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from jointangle.bench.protocol import synthetic_log
from jointangle.cli.main import main
from jointangle.protocol.framing import decode_stream, frame_summary
from jointangle.recording.jrec import MAX_RECORD, JrecReader, JrecWriter

CHUNK = 97  # bytes per record: frames (70 bytes) straddle records
RECORD = 12 + CHUNK
T0_REAL = 1_733_000_000 * 10**9  # a wall-clock receive time (ns since the epoch)


def _write(path: Path, data: bytes, t0: int = 0, step: int = 1_000_000,
           times: list[int] | None = None) -> int:
    """Record data in CHUNK-byte reads; returns the byte offset of the first record."""
    with JrecWriter(path, {"port": "sim://native"}) as w:
        for i in range(0, len(data), CHUNK):
            k = i // CHUNK
            w.write(data[i : i + CHUNK], host_ns=times[k] if times else t0 + step * k)
    return JrecReader.open(path).records_start


def _set_length(raw: bytes, at: int, length: int) -> bytes:
    return raw[:at] + struct.pack("<I", length) + raw[at + 4 :]


def _zero(raw: bytes, at: int, n: int) -> bytes:
    return raw[:at] + bytes(n) + raw[at + n :]


def _replay(path: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    assert main(["replay", str(path), "--json"]) == 0
    doc: dict[str, Any] = json.loads(capsys.readouterr().out)
    return doc


def _frames_after(data: bytes, offset: int) -> int:
    """How many frames of data lie wholly after byte `offset` (the first delimiter at or after
    it ends a frame that may have been hit)."""
    return data.count(0, data.index(0, offset) + 1)


DATA = synthetic_log(1500)  # ~105 kB: ~1085 records
FULL, _ = decode_stream(DATA)
N_RECORDS = -(-len(DATA) // CHUNK)
MID = N_RECORDS // 2

Damage = Callable[[bytes, int], bytes]
LENGTH_DAMAGE: dict[str, Damage] = {
    "huge": lambda raw, first: _set_length(raw, first + MID * RECORD, 0xFFFFFFF0),
    "just over the bound": lambda raw, first: _set_length(raw, first + MID * RECORD,
                                                          MAX_RECORD + 1),
    "large, past the end": lambda raw, first: _set_length(raw, first + MID * RECORD, 100_000),
    "large, within the file": lambda raw, first: _set_length(raw, first + MID * RECORD, 30_000),
    "too short": lambda raw, first: _set_length(raw, first + MID * RECORD, 3),
    "zero": lambda raw, first: _set_length(raw, first + MID * RECORD, 0),
    "first record": lambda raw, first: _set_length(raw, first, 0xFFFFFFF0),
    "last record": lambda raw, first: _set_length(raw, first + (N_RECORDS - 1) * RECORD,
                                                  0xFFFFFFF0),
}


@pytest.mark.parametrize("t0", [0, T0_REAL], ids=["t from 0", "wall clock"])
@pytest.mark.parametrize("kind", list(LENGTH_DAMAGE))
def test_a_damaged_record_length_loses_nothing(kind: str, t0: int, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """Only the length field is hit: every byte the device sent is still read, in order."""
    clean = tmp_path / "clean.jrec"
    first = _write(clean, DATA, t0)
    bad = tmp_path / "bad.jrec"
    bad.write_bytes(LENGTH_DAMAGE[kind](clean.read_bytes(), first))
    rec = JrecReader.open(bad)
    assert rec.damaged_records == 1 and len(rec.damage) == 1
    assert "byte offset" in rec.damage[0] and "damaged" in rec.damage[0]
    assert rec.partial is None and rec.truncated_bytes == 0  # damage, not a cut
    assert rec.data() == DATA
    doc = _replay(bad, capsys)
    ref = _replay(clean, capsys)
    for key in ("frames", "frames_lost", "crc_errors", "bytes_skipped"):
        assert doc[key] == ref[key], key
    assert doc["frames"] == len(FULL) and doc["truncated_bytes"] == 0
    assert doc["file_damage"] == rec.damage
    assert doc["damaged_records"] == rec.damaged_records == len(rec.damage)


@pytest.mark.parametrize("t0", [0, T0_REAL], ids=["t from 0", "wall clock"])
@pytest.mark.parametrize("where", [-50, -5, 0, 7, 40])
def test_zeroed_bytes_over_a_header(where: int, t0: int, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """200 zeroed bytes over record headers: the frames they hit are gone (and counted by the
    decoder), every frame after them is read, and the damage is named."""
    path = tmp_path / "r.jrec"
    first = _write(path, DATA, t0)
    at = first + MID * RECORD + where
    path.write_bytes(_zero(path.read_bytes(), at, 200))
    rec = JrecReader.open(path)
    assert rec.damaged_records >= 1 and rec.damage
    assert rec.partial is None and rec.truncated_bytes == 0
    got, _ = decode_stream(rec.data())
    # Data after the record that holds the last zeroed byte is untouched.
    resume = (at + 200 - first) // RECORD + 1
    after = _frames_after(DATA, resume * CHUNK)
    assert after > 500
    assert frame_summary(got)[-after:] == frame_summary(FULL)[-after:]
    assert len(FULL) - 6 <= len(got) < len(FULL)
    doc = _replay(path, capsys)
    assert doc["frames"] == len(got) and doc["file_damage"] == rec.damage
    assert int(doc["bytes_skipped"]) + int(doc["frames_lost"]) > 0


def test_several_damaged_spans(tmp_path: Path) -> None:
    path = tmp_path / "r.jrec"
    first = _write(path, DATA, T0_REAL)
    raw = path.read_bytes()
    for k in (100, 400, 700):
        raw = _set_length(raw, first + k * RECORD, 0xFFFF0000 + k)
    raw = _zero(raw, first + 900 * RECORD - 30, 200)
    rec = JrecReader.parse(raw)
    assert rec.damaged_records == 4 and len(rec.damage) == 4
    got, _ = decode_stream(rec.data())
    after = _frames_after(DATA, (900 + 2) * CHUNK)
    assert frame_summary(got)[-after:] == frame_summary(FULL)[-after:]
    assert len(got) >= len(FULL) - 6


def test_a_cut_recording_is_still_a_cut(tmp_path: Path) -> None:
    """The last record cut short (a kill): reported as a cut, every complete frame read."""
    path = tmp_path / "r.jrec"
    _write(path, DATA, T0_REAL)
    raw = path.read_bytes()
    for cut in (41, RECORD - 3, 5):  # inside the last record's data, inside its header
        rec = JrecReader.parse(raw[: len(raw) - cut])
        assert rec.damage == [] and rec.damaged_records == 0
        assert rec.truncated_bytes > 0
        assert DATA.startswith(rec.data())
        got, _ = decode_stream(rec.data())
        assert len(got) == rec.data().count(0)


def test_damage_then_a_cut(tmp_path: Path) -> None:
    path = tmp_path / "r.jrec"
    first = _write(path, DATA, T0_REAL)
    raw = _set_length(path.read_bytes(), first + MID * RECORD, 0xFFFFFFF0)
    rec = JrecReader.parse(raw[: len(raw) - 41])
    assert rec.damaged_records == 1 and rec.partial is not None and rec.truncated_bytes > 0
    assert DATA.startswith(rec.data()) and len(rec.data()) == len(DATA) - 41


def test_clock_steps_are_not_damage(tmp_path: Path) -> None:
    """Receive times that jump back by minutes or ahead by a day are not a damaged file."""
    times = [T0_REAL + 1_000_000 * k for k in range(N_RECORDS)]
    for k in range(300, N_RECORDS):
        times[k] -= 5 * 60 * 10**9
    for k in range(600, N_RECORDS):
        times[k] += 86_400 * 10**9
    path = tmp_path / "r.jrec"
    _write(path, DATA, times=times)
    rec = JrecReader.open(path)
    assert rec.damage == [] and rec.data() == DATA
    assert [r.host_ns for r in rec.records] == times
    first = _write(tmp_path / "again.jrec", DATA, times=times)
    bad = _set_length((tmp_path / "again.jrec").read_bytes(), first + 650 * RECORD, 1 << 30)
    rec = JrecReader.parse(bad)
    assert rec.damaged_records == 1 and rec.data() == DATA


def test_nothing_after_a_damaged_header_is_refused(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A lone damaged header with no byte after it holds nothing to recover: refused."""
    path = tmp_path / "r.jrec"
    with JrecWriter(path, {"port": "loop://"}) as w:
        w.write(b"\x05abcd\x00", host_ns=1)
    raw = path.read_bytes()
    path.write_bytes(_set_length(raw[: len(raw) - 6], len(raw) - 18, 0xFFFFFFF0))
    assert main(["replay", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "damaged" in err and "nothing to recover" in err
