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
