"""A `.jrec` survives any single flipped bit (issue 16 item 2): for every bit of the first 2 KB
(preamble, metadata, guard, the copy's start) and 1 000 random bits after it, the reader gives
back every record the flip did not touch, the metadata intact (from one of its two copies), and
names the damage in the header; `replay --json`'s summary reads it (in-process: one parse per
flip, no subprocess)."""

from __future__ import annotations

import json
import random
from pathlib import Path

import pytest

from jointangle.bench.protocol import synthetic_log
from jointangle.cli.replay import summarize
from jointangle.errors import InputError
from jointangle.recording.jrec import JrecReader, JrecWriter

T0 = 1_733_000_000 * 10**9
CHUNK = 97

RIG = """name = "bench-L30"
sample_rate_hz = 500

[links.a]
joint = [0.30, 0.0]
[[links.a.sensors]]
model = "adxl345"
position = [0.25, 0.0]
mux_channel = 0
address = 0x53
range_g = 2
[[links.a.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 0
address = 0x1D
range_g = 2

[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 1
address = 0x53
range_g = 2
[[links.b.sensors]]
model = "adxl345"
position = [0.25, 0.0]
mux_channel = 1
address = 0x1D
range_g = 2
"""
HELLO = {"protocol_version": 1, "schema_hash": 305419896, "firmware_major": 0,
         "firmware_minor": 9, "firmware_patch": 1, "build": "fake-1", "board": 1,
         "sample_rate_hz": 500, "stream_mode": 0, "eeprom": 0,
         "sensors": [{"link": k // 2, "model": 1, "mux_channel": k // 2, "address": 83,
                      "chip_id": 229, "range_g": 2, "status": 0} for k in range(4)]}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("flips") / "r.jrec"
    data = synthetic_log(80)
    meta = {"rig": RIG, "hello": HELLO, "port": "/dev/ttyACM0",
            "host": {"name": "lab-pc", "jointangle": "0.9.1", "start_unix_ns": T0}}
    with JrecWriter(path, meta) as w:
        for k in range(0, len(data), CHUNK):
            w.write(data[k : k + CHUNK], host_ns=T0 + 2_000_000 * k)
    return path.read_bytes()


def _check(raw: bytes, clean: JrecReader, bit: int) -> None:
    at = bit // 8
    bad = bytearray(raw)
    bad[at] ^= 1 << (bit % 8)
    try:
        rec = JrecReader.parse(bytes(bad))
    except InputError as exc:  # allowed only if it names the damage and nothing was lost
        raise AssertionError(f"bit {bit} (byte {at}): refused: {exc}") from None
    got = {(r.host_ns, r.data) for r in rec.records}
    pos = clean.records_start
    for r in clean.records:
        end = pos + 12 + len(r.data)
        if not pos <= at < end:  # not touched by the flip
            assert (r.host_ns, r.data) in got, (bit, at, pos)
        pos = end
    if at < clean.records_start:
        assert rec.metadata == clean.metadata, (bit, at, rec.damage)
        assert rec.damage, (bit, at)  # named
        assert all("byte offset" in d or "bytes " in d for d in rec.damage)


def test_every_bit_of_the_first_2_kb(recording: bytes) -> None:
    clean = JrecReader.parse(recording)
    assert clean.damage == [] and clean.records_start > 2048  # the header fills the first 2 KB
    for bit in range(2048 * 8):
        _check(recording, clean, bit)


def test_1000_random_bits_after_the_first_2_kb(recording: bytes) -> None:
    clean = JrecReader.parse(recording)
    rnd = random.Random(16)
    for _ in range(1000):
        _check(recording, clean, rnd.randrange(2048 * 8, len(recording) * 8))


@pytest.mark.parametrize("at", [3, 9, 11, 20, 600, 1500])
def test_replay_names_the_damage_and_what_it_fell_back_on(recording: bytes, at: int,
                                                          tmp_path: Path) -> None:
    clean = JrecReader.parse(recording)
    bad = bytearray(recording)
    bad[at] ^= 0x10
    rec = JrecReader.parse(bytes(bad))
    doc = summarize(rec)
    ref = summarize(clean)
    assert doc["frames"] == ref["frames"] and doc["file_damage"]
    assert doc["metadata_source"] in ("header", "copy")
    json.dumps(doc)


def test_without_any_metadata_the_records_are_read_and_rig_supplies_the_rig(
        recording: bytes, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from jointangle.cli.main import main

    clean = JrecReader.parse(recording)
    n = int.from_bytes(recording[10:14], "little")
    bad = bytearray(recording)
    bad[14 + 5] ^= 0x04  # both copies of the metadata hit
    bad[14 + n + 24 + 5] ^= 0x04
    path = tmp_path / "bad.jrec"
    path.write_bytes(bytes(bad))
    rec = JrecReader.parse(bytes(bad))
    assert rec.metadata == {} and rec.metadata_source == "none"
    assert rec.records == clean.records and "--rig" in rec.damage[0]
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG)
    csv = tmp_path / "est.csv"
    assert main(["replay", str(path), "--json", "--rig", str(rig), "--estimates-csv",
                 str(csv)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["rig_source"] == "--rig" and doc["metadata_source"] == "none"
    assert doc["frames"] == summarize(clean)["frames"] and doc["estimate_rows"] > 0
    assert main(["replay", str(path), "--verify"]) == 2  # no rig: says where to give it
    assert "--rig" in capsys.readouterr().err
