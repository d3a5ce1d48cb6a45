"""Link faults between a device and the host (issue 16 items 1 and 3): frames of another
protocol version, of unknown message ids, duplicated, swapped and stale frames are injected by
the fake device on its pty; `record`, `live --json` and `replay --json` keep going and report
exactly what was injected, with the same numbers from all three."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fake_device import FakeData, FakeDevice, FakeFaults

from jointangle.cli.main import main

SECONDS = "0.8"  # 400 stream frames at 500 Hz: the faults below sit well inside


def _json(capsys: pytest.CaptureFixture[str], argv: list[str], code: int = 0) -> dict:
    capsys.readouterr()
    assert main(argv) == code
    return json.loads(capsys.readouterr().out)


def _record_replay_live(tmp_path: Path, data: FakeData, rig: Path, faults: FakeFaults,
                        capsys: pytest.CaptureFixture[str]) -> tuple[dict, dict, dict, dict]:
    out = tmp_path / "run.jrec"
    with FakeDevice(data, tmp_path, faults) as fake:
        rec = _json(capsys, ["record", "--port", str(fake.path), "--seconds", SECONDS, "--out",
                             str(out), "--rig", str(rig), "--json"])
        injected = dict(fake.counts.injected)
    with FakeDevice(data, tmp_path, faults, name="fake-live") as fake:
        live = _json(capsys, ["live", "--port", str(fake.path), "--seconds", SECONDS, "--json"])
    rep = _json(capsys, ["replay", str(out), "--json"])
    return injected, rec, live, rep


def test_other_versions_and_unknown_ids_are_counted_never_fatal(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(inject={50: "version", 120: "unknown", 200: "version"})
    injected, rec, live, rep = _record_replay_live(tmp_path, fake_data[0], rig_file, faults,
                                                   capsys)
    assert injected == {"version": 2, "unknown": 1}
    assert rec["complete"]
    for doc in (rec, live, rep):
        assert doc["version_errors"] == 2 and doc["unknown_messages"] == 1
        assert doc["versions_seen"]["2"] == 2
        assert doc["frames_lost"] == 0 and doc["crc_errors"] == 0
    assert rep["frames"] == rec["frames"] and rep["versions_seen"] == rec["versions_seen"]
    assert rep["messages"]["sample_estimate"] == rec["samples"] > 300
    assert rep["messages"]["0x3E"] == 1


def test_duplicated_swapped_and_stale_frames_are_not_losses(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    inject = {10: "duplicate", 40: "swap", 41: "duplicate", 70: "duplicate", 110: "swap",
              310: "stale", 330: "stale", 200: "swap"}
    faults = FakeFaults(inject=inject, drop=frozenset({150, 151}))
    injected, rec, live, rep = _record_replay_live(tmp_path, fake_data[0], rig_file, faults,
                                                   capsys)
    assert injected == {"duplicate": 3, "swap": 3, "stale": 2}
    for doc in (rec, live, rep):
        # Today: ~65 535 per duplicate, swap or stale frame.
        assert doc["frames_lost"] == 2, doc
        assert (doc["duplicates"], doc["out_of_order"], doc["stale"]) == (3, 3, 2), doc
        assert doc["segments"] == 1
    for key in ("frames_lost", "duplicates", "out_of_order", "stale", "segments"):
        assert rec[key] == rep[key] == live[key], key
    assert rec["frames"] == rep["frames"]  # (live ran a session of its own)
    assert rep["messages"]["sample_estimate"] == rec["samples"]


def test_replay_verify_and_export_take_each_frame_once(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.jrec"
    faults = FakeFaults(inject={20: "duplicate", 330: "stale"})
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        rec = _json(capsys, ["record", "--port", str(fake.path), "--seconds", SECONDS, "--out",
                             str(out), "--rig", str(rig_file), "--json"])
    csv = tmp_path / "est.csv"
    rep = _json(capsys, ["replay", str(out), "--json", "--verify", "--estimates-csv", str(csv)])
    assert rep["estimate_rows"] == rec["samples"] == rep["messages"]["sample_estimate"]
    # Nothing to re-follow: the duplicate and the stale copy were never fed to the mirror.
    assert rep["segments"] == 1 and rep["unverified_frames"] == 0, rep
    assert rep["max_abs_dtheta_deg"] < 1e-3
    assert (rep["duplicates"], rep["frames_lost"]) == (1, 0)


def test_the_view_shows_what_the_link_did(fake_data: tuple[FakeData, str]) -> None:
    import io

    from rich.console import Console

    from jointangle.device.rig import device_rig
    from jointangle.live.session import LiveState
    from jointangle.live.view import render
    from jointangle.protocol import messages as msgs
    from jointangle.rig import parse_rig

    data, rig_text = fake_data
    hello = msgs.Hello(1, msgs.SCHEMA_HASH, 0, 9, 1, b"fake", msgs.Board.NATIVE, data.rate_hz,
                       4, 0, data.sensors)
    state = LiveState(hello, device_rig(parse_rig(rig_text), hello))

    def shown(stats: dict[str, int]) -> str:
        buf = io.StringIO()
        Console(file=buf, width=80, height=24, color_system=None).print(
            render(state, port="/dev/pts/7", stats=stats))
        return buf.getvalue()

    assert "link:" not in shown({"frames": 10, "segments": 1})
    text = shown({"frames": 10, "duplicates": 3, "out_of_order": 2, "stale": 1,
                  "version_errors": 1, "segments": 2})
    assert "link: 3 duplicated, 2 late, 1 stale, 1 other-version, 2 segments" in text
