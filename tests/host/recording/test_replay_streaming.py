"""replay --verify in one pass with bounded memory (issue 16 item 6): the lazy reader and the
streaming verifier give exactly what reading the whole recording gives, whatever the chunking,
across losses, CRC errors, a pulled cable, filter restarts and file damage."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fake_device import FakeData, FakeDevice, FakeFaults

from jointangle.cli import replay
from jointangle.cli.main import main
from jointangle.recording import jrec, stream_export, stream_verify
from jointangle.recording.jrec import JrecReader


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory, fake_data: tuple[FakeData, str]) -> Path:
    """~4 s at 500 Hz with lost and corrupted frames, duplicates, a stale frame, a pulled cable
    and the filter restarted after it (two runs)."""
    d = tmp_path_factory.mktemp("stream")
    rig = d / "rig.toml"
    rig.write_text(fake_data[1])
    out = d / "run.jrec"
    faults = FakeFaults(drop=frozenset({100, 101, 700}), corrupt=frozenset({250, 1200}),
                        inject={400: "duplicate", 900: "stale"}, disconnect_after=1000,
                        reconnect_after_s=0.3)
    with FakeDevice(fake_data[0], d, faults) as fake:
        assert main(["record", "--port", str(fake.path), "--seconds", "4", "--out", str(out),
                     "--rig", str(rig), "--json", "--retry-delay", "0.2"]) == 0
    return out


@pytest.fixture(autouse=True)
def _lazy_at_any_size(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jrec, "LAZY_MIN_BYTES", 0)  # (a lazy reader reads small files whole)


@pytest.fixture(scope="module")
def whole(recording: Path) -> dict:
    rec = JrecReader.open(recording)
    doc = replay.summarize(rec)
    doc.update(replay.verify(rec))
    return doc


@pytest.mark.parametrize("chunk", [37, 1000, stream_verify.CHUNK_FRAMES])
def test_streaming_verify_equals_the_whole_file(recording: Path, whole: dict, chunk: int,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stream_verify, "CHUNK_FRAMES", chunk)
    rec = JrecReader.open(recording, lazy=True)
    assert rec.records == []  # nothing read yet
    v = stream_verify.StreamVerifier(replay.recording_rig(rec, "--verify"), rec.metadata)
    doc = replay.summarize(rec, v.frame)
    doc.update(v.result())
    rec.close()
    assert doc == whole
    assert whole["segments"] >= 2 and whole["frames_lost"] > 0 and whole["duplicates"] == 1
    assert whole["verified_frames"] > 200 and whole["unverified_frames"] > 1000  # losses


def test_replay_verify_takes_the_streaming_path(recording: Path, whole: dict,
                                                capsys: pytest.CaptureFixture[str],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    def whole_file(rec: JrecReader) -> dict:
        raise AssertionError("read whole")

    monkeypatch.setattr(replay, "verify", whole_file)
    capsys.readouterr()
    assert main(["replay", str(recording), "--verify", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    doc.pop("rig_source")
    assert doc == whole


def test_a_lazy_reader_reads_damage_as_the_whole_one(recording: Path, tmp_path: Path) -> None:
    raw = bytearray(recording.read_bytes())
    clean = JrecReader.parse(bytes(raw))
    for k in (5, 200, 201, len(clean.records) - 2):  # record lengths hit
        at = clean.records_start + sum(12 + len(r.data) for r in clean.records[:k])
        raw[at + 2] ^= 0x40
    raw[20] ^= 0x01  # and the metadata: read from its copy
    bad = tmp_path / "bad.jrec"
    bad.write_bytes(bytes(raw))
    ref = JrecReader.open(bad)
    lazy = JrecReader.open(bad, lazy=True)
    for _ in range(2):  # each pass reads the same
        got = [(r.host_ns, r.data) for r in lazy.chunks()]
        assert got == [(r.host_ns, r.data) for r in ref.chunks()]
        assert (lazy.damage, lazy.damaged_records, lazy.record_count, lazy.metadata) == \
            (ref.damage, ref.damaged_records, ref.record_count, ref.metadata)
    assert ref.damaged_records >= 3 and ref.metadata_source == "copy"
    lazy.close()


@pytest.mark.parametrize("chunk", [37, stream_export.CHUNK_FRAMES])
def test_streaming_export_writes_the_whole_file_csvs(recording: Path, tmp_path: Path,
                                                     chunk: int,
                                                     capsys: pytest.CaptureFixture[str],
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    from jointangle.recording.export import accelerations_table, estimates_table

    rec = JrecReader.open(recording)
    accelerations_table(rec).write(tmp_path / "acc-whole.csv")
    estimates_table(rec).write(tmp_path / "est-whole.csv")
    monkeypatch.setattr(stream_export, "CHUNK_FRAMES", chunk)
    monkeypatch.setattr(replay, "_export", lambda *a: pytest.fail("read whole"))
    capsys.readouterr()
    assert main(["replay", str(recording), "--json", "--verify", "--accel-csv",
                 str(tmp_path / "acc.csv"), "--estimates-csv", str(tmp_path / "est.csv")]) == 0
    doc = json.loads(capsys.readouterr().out)
    for name in ("acc", "est"):
        assert (tmp_path / f"{name}.csv").read_text() == \
            (tmp_path / f"{name}-whole.csv").read_text(), name
    assert doc["accel_rows"] == doc["estimate_rows"] == doc["messages"]["sample_estimate"]
    assert not list(tmp_path.glob(".jointangle-export-*"))  # the spool files are gone


def test_streaming_export_checks_before_writing(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """No sensor inventory (no hello frame, none in the metadata): refused in one line, neither
    CSV written."""
    from jointangle.recording.jrec import JrecWriter

    empty = tmp_path / "empty.jrec"
    with JrecWriter(empty, {"port": "x"}) as w:
        w.write(b"\x05abcd\x00", host_ns=1)
    capsys.readouterr()
    assert main(["replay", str(empty), "--accel-csv", str(tmp_path / "a.csv"),
                 "--estimates-csv", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no sensor inventory" in err
    assert not (tmp_path / "a.csv").exists() and not (tmp_path / "e.csv").exists()
