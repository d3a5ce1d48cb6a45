"""Reconnects (issue 16 item 7): live reconnects like record (--retries, --retry-delay, --stall,
'reconnecting…' in its events), and after any reconnect both restart the board's filter when
they started it, so a recording made across a pulled cable verifies segment by segment."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fake_device import FakeData, FakeDevice, FakeFaults

from jointangle.cli.main import main


def _json(capsys: pytest.CaptureFixture[str], argv: list[str], code: int = 0) -> dict:
    capsys.readouterr()
    assert main(argv) == code
    return json.loads(capsys.readouterr().out)


def test_record_restarts_the_filter_after_a_reconnect_and_verifies_both_runs(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.jrec"
    faults = FakeFaults(disconnect_after=300, reconnect_after_s=0.3)
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        doc = _json(capsys, ["record", "--port", str(fake.path), "--seconds", "2", "--out",
                             str(out), "--rig", str(rig_file), "--json", "--retry-delay", "0.2"])
        commands = list(fake.counts.commands)
    assert doc["complete"] and doc["reconnects"] == 1
    assert commands.count("restart_filter") == 2  # at the start and after the reconnect
    rep = _json(capsys, ["replay", str(out), "--json", "--verify"])
    assert rep["segments"] == 2  # two filter runs, each followed from its first step
    # Unverifiable: only the frames between a start_stream and the restart_filter after it.
    assert rep["unverified_frames"] <= 10, rep
    assert rep["verified_frames"] > 500 and rep["max_abs_dtheta_deg"] < 1e-3


def test_live_reconnects_with_its_options_and_restarts_the_filter(
        tmp_path: Path, fake_data: tuple[FakeData, str],
        capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(disconnect_after=150, reconnect_after_s=0.3)
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        s = _json(capsys, ["live", "--port", str(fake.path), "--seconds", "2", "--json",
                           "--retries", "3", "--retry-delay", "0.2", "--stall", "1"])
        commands = list(fake.counts.commands)
    assert s["disconnects"] == 1 and s["reconnects"] == 1
    assert any(e.endswith("reconnecting…") for e in s["events"]) and "reconnected" in s["events"]
    assert commands.count("restart_filter") == 2
    with FakeDevice(fake_data[0], tmp_path, FakeFaults(disconnect_after=150),
                    name="gone") as fake:
        capsys.readouterr()
        assert main(["live", "--port", str(fake.path), "--seconds", "3", "--json",
                     "--retries", "0"]) == 1
    got = capsys.readouterr()
    s = json.loads(got.out)
    assert s["disconnects"] == 1 and s["reconnects"] == 0
    assert "did not come back after 0 tries" in got.err
