"""Recordings: write/read, truncation at every byte, CSV export, `replay --json`, the bench."""

from __future__ import annotations

import argparse
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from jointangle.bench.protocol import corrupt, run_protocol_bench, synthetic_log
from jointangle.cli import replay
from jointangle.errors import InputError
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.framing import decode_stream, frame_summary
from jointangle.recording.export import export_accelerations, export_estimates, unwrap_us
from jointangle.recording.jrec import MAGIC, JrecReader, JrecWriter


def _chunks(data: bytes, size: int = 97) -> list[bytes]:
    return [data[i : i + size] for i in range(0, len(data), size)]


def _record(path: Path, data: bytes, meta: dict[str, object] | None = None) -> None:
    with JrecWriter(path, meta or {"port": "sim://native"}) as w:
        for i, chunk in enumerate(_chunks(data)):
            w.write(chunk, host_ns=1_000_000 * i)


def _run_replay(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    replay.register(sub)
    args = parser.parse_args(["replay", *argv])
    assert args.func(args) == 0
    return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]


def test_round_trip(tmp_path: Path) -> None:
    data = synthetic_log(300)
    path = tmp_path / "r.jrec"
    _record(path, data, {"rig": "name = 'x'", "port": "loop://"})
    rec = JrecReader.open(path)
    assert rec.metadata["rig"] == "name = 'x'" and rec.metadata["port"] == "loop://"
    assert rec.data() == data and rec.truncated_bytes == 0 and rec.partial is None
    assert [r.host_ns for r in rec.records] == [1_000_000 * i for i in range(len(rec.records))]
    with pytest.raises(InputError, match="already exists"):
        JrecWriter(path)


def test_truncated_at_every_byte_keeps_every_complete_frame(tmp_path: Path) -> None:
    data = synthetic_log(12)
    path = tmp_path / "r.jrec"
    _record(path, data)
    raw = path.read_bytes()
    full, _ = decode_stream(data)
    header_end = JrecReader.parse(raw).records_start  # metadata, guard and its copy
    for cut in range(len(raw) + 1):
        rec = JrecReader.parse(raw[:cut])
        got, _ = decode_stream(rec.data())
        # Every frame whose bytes (delimiter included) were all written before the cut.
        available = rec.data()
        assert data.startswith(available)
        complete = decode_stream(available)[0]
        assert frame_summary(got) == frame_summary(complete)
        assert frame_summary(got) == frame_summary(full[: len(got)])
        expected = sum(1 for i in range(len(data)) if data[i] == 0 and i < len(available))
        assert len(got) == expected
        assert rec.header_truncated == (cut < header_end)


def test_bad_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"not a \.jrec"):
        JrecReader.parse(b"t,a.0.x\n0,1\n")
    newer = struct.pack("<8sHI", MAGIC, 99, 2) + b"{}"
    with pytest.raises(InputError, match="format version 99"):
        JrecReader.parse(newer)
    with pytest.raises(InputError, match="cannot read"):
        JrecReader.open(tmp_path / "missing.jrec")


@pytest.mark.parametrize(("raw", "reason"), [
    (b"", "empty file: not a jointangle recording"),
    (MAGIC[:3], "cut short before the end of its header (3 of 14 bytes)"),
    (struct.pack("<8sHI", MAGIC, 1, 40) + b'{"port": ', "cut short inside its header"),
])
def test_a_file_without_a_complete_header_is_refused(
        raw: bytes, reason: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """They read as valid empty recordings (0 frames, exit 0)."""
    from jointangle.cli.main import main

    path = tmp_path / "short.jrec"
    path.write_bytes(raw)
    with pytest.raises(InputError, match=re.escape(reason)):
        JrecReader.open(path)
    assert main(["replay", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and reason in err


def _flip(raw: bytes, offset: int, value: int) -> bytes:
    return raw[:offset] + bytes([value]) + raw[offset + 1 :]


@pytest.mark.parametrize(("offset", "value"), [(13, 0x80), (11, 0x7F), (10, 0x03)])
def test_a_damaged_metadata_length_is_reported_and_the_records_recovered(
        offset: int, value: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A flipped length byte read as 'cut short' with 0 frames and exit 0. Beyond the file's
    end (13, 11) or short of the metadata's end (10): the reader finds where the metadata
    really ends, reads every record after it and names the damaged offset."""
    data = synthetic_log(300)
    clean = tmp_path / "clean.jrec"
    _record(clean, data)
    raw = clean.read_bytes()
    bad = tmp_path / "bad.jrec"
    bad.write_bytes(_flip(raw, offset, value))
    rec = JrecReader.open(bad)
    assert rec.data() == data and rec.metadata == JrecReader.open(clean).metadata
    assert len(rec.damage) == 1 and "byte offset 10" in rec.damage[0]
    doc = _run_replay([str(bad), "--json"], capsys)
    assert doc["frames"] == _run_replay([str(clean), "--json"], capsys)["frames"] > 300
    assert "metadata length at byte offset 10 is damaged" in doc["file_damage"][0]


def test_a_damaged_header_with_nothing_after_it_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from jointangle.cli.main import main

    path = tmp_path / "empty.jrec"
    JrecWriter(path, {"port": "loop://"}).close()  # a header and no record
    path.write_bytes(_flip(path.read_bytes(), 13, 0x80))
    assert main(["replay", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "byte offset 10" in err and "nothing to recover" in err


def _version_1(meta: bytes, data: bytes) -> bytes:
    """A recording as the version-1 writer made it: no guard, no copy of the metadata."""
    out = struct.pack("<8sHI", MAGIC, 1, len(meta)) + meta
    for i, chunk in enumerate(_chunks(data)):
        out += struct.pack("<IQ", len(chunk), 1_000_000 * i) + chunk
    return out


def test_damaged_metadata_is_read_from_its_copy(tmp_path: Path) -> None:
    path = tmp_path / "r.jrec"
    data = synthetic_log(10)
    _record(path, data)
    raw = path.read_bytes()
    clean = JrecReader.parse(raw)
    assert clean.damage == [] and clean.format_version == 2
    at = raw.index(b'"port"')
    rec = JrecReader.parse(_flip(raw, at, ord("?")))
    assert rec.metadata == clean.metadata and rec.metadata_source == "copy"
    assert rec.data() == data
    n = struct.unpack_from("<I", raw, 10)[0]  # metadata length
    assert clean.records_start == 14 + n + 24 + n
    assert rec.damage == [f"metadata (bytes 14-{13 + n}) is damaged: read from its second copy "
                          f"(bytes {14 + n + 24}-{clean.records_start - 1})"]


def test_version_1_files_are_still_read(tmp_path: Path) -> None:
    data = synthetic_log(10)
    raw = _version_1(b'{"port": "loop://"}', data)
    rec = JrecReader.parse(raw)
    assert rec.format_version == 1 and rec.metadata == {"port": "loop://"}
    assert rec.data() == data and rec.damage == []
    at = raw.index(b'"port"')
    with pytest.raises(InputError, match=f"not valid JSON at byte offset {at}"):
        JrecReader.parse(_flip(raw, at, ord("?")))


def test_replay_json_counts_clean_and_damaged(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    data = synthetic_log(2000)
    clean = tmp_path / "clean.jrec"
    _record(clean, data)
    doc = _run_replay([str(clean), "--json"], capsys)
    assert {k: doc[k] for k in ("frames", "frames_lost", "crc_errors", "bytes_skipped")} == {
        "frames": 2004, "frames_lost": 0, "crc_errors": 0, "bytes_skipped": 0}
    bad = corrupt(data, fraction=2e-4)
    damaged = tmp_path / "damaged.jrec"
    _record(damaged, bad)
    doc = _run_replay([str(damaged), "--json"], capsys)
    ref = bulk_decode(bad).stats.as_dict()
    for key in ("frames", "frames_lost", "crc_errors", "bytes_skipped", "malformed"):
        assert doc[key] == ref[key]
    assert int(doc["frames"]) < 2004 and int(doc["bytes_skipped"]) > 0


def test_replay_of_a_cut_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = synthetic_log(100)
    path = tmp_path / "cut.jrec"
    _record(path, data)
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) - 41])
    doc = _run_replay([str(path), "--json"], capsys)
    assert int(doc["truncated_bytes"]) > 0
    assert doc["frames"] == sum(1 for b in JrecReader.open(path).data() if b == 0)


def test_replay_verify_explains_what_is_missing(tmp_path: Path) -> None:
    path = tmp_path / "r.jrec"
    _record(path, synthetic_log(10))
    parser = argparse.ArgumentParser()
    replay.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["replay", str(path), "--verify", "--json"])
    with pytest.raises(InputError, match=r"mirror|rig"):
        args.func(args)


def test_csv_export(tmp_path: Path) -> None:
    data = synthetic_log(50)
    path = tmp_path / "r.jrec"
    _record(path, data)
    rec = JrecReader.open(path)
    n = export_accelerations(rec, tmp_path / "acc.csv")
    assert n == 50
    lines = (tmp_path / "acc.csv").read_text().splitlines()
    assert lines[0] == "t,a.0.x,a.0.y,a.0.z,a.1.x,a.1.y,a.1.z,b.0.x,b.0.y,b.0.z,b.1.x,b.1.y,b.1.z"
    table = np.loadtxt(tmp_path / "acc.csv", delimiter=",", skiprows=1)
    assert table.shape == (50, 13)
    assert np.allclose(np.diff(table[:, 0]), 0.002)
    assert 8.0 < np.mean(table[:, 3]) < 11.5  # z ≈ 1 g from 256 counts of 3.9 mg
    assert export_estimates(rec, tmp_path / "est.csv") == 50
    est = np.loadtxt(tmp_path / "est.csv", delimiter=",", skiprows=1)
    assert est.shape == (50, 5)
    t = np.arange(50) / 500.0
    assert np.allclose(est[:, 1], np.degrees(0.8 * np.sin(2 * np.pi * 0.2 * t)), atol=1e-5)


def test_unwrap_us() -> None:
    t = np.array([2**32 - 2000, 2**32 - 1000, 0, 1000, 2000], dtype=np.uint32)
    assert list(np.diff(unwrap_us(t))) == [1000] * 4


def test_bench_protocol_reports_all_keys_and_agrees() -> None:
    doc = run_protocol_bench(3000, stream_frames=500, construct_frames=200, repeats=1)
    for key in ("bulk_frames_per_s", "stream_frames_per_s", "construct_frames_per_s",
                "frame_bytes"):
        assert key in doc and doc[key] > 0
    assert doc["frame_bytes"] == 70 <= 80
    assert doc["log_frames"] == 3000 + 5 + 1


def test_bench_protocol_cli(capsys: pytest.CaptureFixture[str]) -> None:
    from jointangle.cli import bench_protocol

    parser = argparse.ArgumentParser()
    bench_protocol.register(parser.add_subparsers(dest="kind"))
    args = parser.parse_args(["protocol", "--json", "--frames", "1000"])
    assert args.func(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"bulk_frames_per_s", "stream_frames_per_s", "construct_frames_per_s",
            "frame_bytes"} <= set(doc)
    with pytest.raises(InputError, match="--frames"):
        args.func(parser.parse_args(["protocol", "--frames", "10"]))
