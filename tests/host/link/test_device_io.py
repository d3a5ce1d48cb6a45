"""info, record, replay (--verify) against a device on a serial port.

The targets are those that exist (`device_targets`): the protocol-speaking fake device on a pty
(fake_device.py) always; the native virtual board (sim://native) once its binary is built; a real
port when one is named in $JOINTANGLE_TEST_PORT (pyserial's PORT pattern). Tests that inject
faults or need to know what was sent use the fake only.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fake_device import FakeData, FakeDevice, FakeFaults, make_data

from jointangle.cli.main import main
from jointangle.protocol import messages as msgs
from jointangle.recording.jrec import JrecReader


def reset_frames(path: Path) -> list[int]:
    """Indices (among the recording's sample_estimate frames) of the frames with health reset."""
    from jointangle.protocol.bulk import bulk_decode

    health = bulk_decode(JrecReader.open(path).data()).columns("sample_estimate")["health"]
    return [int(k) for k in np.flatnonzero(health.astype(np.int64) & msgs.FilterHealth.RESET)]


def run_json(capsys: pytest.CaptureFixture[str], argv: list[str], code: int = 0) -> dict:
    capsys.readouterr()
    assert main(argv) == code
    return json.loads(capsys.readouterr().out)


def test_info_json(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    doc = run_json(capsys, ["info", "--port", port, "--json"])
    assert doc["protocol_version"] == msgs.PROTOCOL_VERSION == doc["host_protocol_version"]
    assert doc["schema_hash"] == f"0x{msgs.SCHEMA_HASH:08X}" == doc["host_schema_hash"]
    assert doc["sensors"] and all(s["link"] in "ab" for s in doc["sensors"])
    assert all(s["chip_id"].startswith("0x") for s in doc["sensors"])
    assert doc["sample_rate_hz"] > 0


@pytest.mark.parametrize(("faults", "message"), [
    (FakeFaults(schema_hash=0x12345678),
     f"schema 0x12345678, this host with 0x{msgs.SCHEMA_HASH:08X}"),
    (FakeFaults(protocol_version=2), "protocol version 2, this host speaks version 1"),
])
def test_info_refuses_another_protocol(tmp_path: Path, fake_data: tuple[FakeData, str],
                                       capsys: pytest.CaptureFixture[str], faults: FakeFaults,
                                       message: str) -> None:
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        assert main(["info", "--port", str(fake.path)]) == 2
    assert message in capsys.readouterr().err


def test_info_on_a_port_without_our_firmware(capsys: pytest.CaptureFixture[str]) -> None:
    # loop:// echoes our own get_info back: frames, but no hello.
    assert main(["info", "--port", "loop://", "--timeout", "0.1"]) == 2
    assert "did not answer get_info" in capsys.readouterr().err


def record(tmp_path: Path, port: str, rig: Path, capsys: pytest.CaptureFixture[str],
           seconds: float = 1.0, code: int = 0, *extra: str) -> tuple[Path, dict]:
    out = tmp_path / "run.jrec"
    doc = run_json(capsys, ["record", "--port", port, "--seconds", str(seconds), "--out",
                            str(out), "--rig", str(rig), "--json", "--retry-delay", "0.2",
                            *extra], code)
    return out, doc


def test_record_then_replay(port: str, tmp_path: Path, rig_file: Path,
                            capsys: pytest.CaptureFixture[str]) -> None:
    out, doc = record(tmp_path, port, rig_file, capsys, 1.0)
    assert doc["complete"] and doc["frames"] > 100
    rec = JrecReader.open(out)
    assert rec.metadata["rig"] == rig_file.read_text()
    assert rec.metadata["hello"]["schema_hash"] == msgs.SCHEMA_HASH
    assert rec.truncated_bytes == 0
    rep = run_json(capsys, ["replay", str(out), "--json"])
    for k in ("frames", "frames_lost", "crc_errors", "bytes_skipped"):
        assert rep[k] == doc[k], k
    assert rep["messages"]["sample_estimate"] == doc["samples"]


def test_replay_counts_what_the_device_sent(tmp_path: Path, fake_data: tuple[FakeData, str],
                                            rig_file: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(drop=frozenset({50, 51, 52, 300}), corrupt=frozenset({100, 200, 201}))
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        out, _ = record(tmp_path, str(fake.path), rig_file, capsys, 1.0)
        c = fake.counts
    assert (c.dropped, c.corrupted) == (4, 3)
    rep = run_json(capsys, ["replay", str(out), "--json"])
    assert rep["frames"] == c.frames_written
    assert rep["frames_lost"] == 7  # dropped and corrupted frames are both sequence gaps
    assert rep["crc_errors"] == 3
    assert rep["bytes_skipped"] > 0 and rep["malformed"] == 0


def test_record_survives_a_pulled_cable(tmp_path: Path, fake_data: tuple[FakeData, str],
                                        rig_file: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(disconnect_after=200)
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        out, doc = record(tmp_path, str(fake.path), rig_file, capsys, 3.0, 1,
                          "--retries", "2")
        c = fake.counts
    assert doc["disconnects"] == 1 and doc["reconnects"] == 0 and not doc["complete"]
    assert "did not come back" in doc["error"]
    rec = JrecReader.open(out)
    assert rec.truncated_bytes == 0  # closed cleanly: every received byte is in the file
    rep = run_json(capsys, ["replay", str(out), "--json"])
    assert rep["frames"] == c.frames_written  # everything sent before the cut was kept
    assert rep["messages"]["sample_estimate"] == 200
    assert rep["frames_lost"] == 0 and rep["crc_errors"] == 0


def test_record_reconnects(tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
                           capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(disconnect_after=150, reconnect_after_s=0.3)
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        out, doc = record(tmp_path, str(fake.path), rig_file, capsys, 1.5)
        c = fake.counts
    assert doc["complete"] and doc["disconnects"] == 1 and doc["reconnects"] == 1
    assert c.connections == 2 and c.commands.count("start_stream") == 2
    rep = run_json(capsys, ["replay", str(out), "--json"])
    assert rep["frames"] == c.frames_written
    assert rep["messages"]["hello"] == 2 and rep["messages"]["sample_estimate"] > 300


def test_a_cut_recording_reads_to_its_last_byte(tmp_path: Path, port: str, rig_file: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out, doc = record(tmp_path, port, rig_file, capsys, 0.5)
    raw = out.read_bytes()
    # Cut a few bytes inside the last record: never exactly on a record boundary (a fixed count
    # could land there), never deep into a long last record (that would drop many frames).
    last = JrecReader.parse(raw).records[-1]
    cut = tmp_path / "cut.jrec"
    cut.write_bytes(raw[: len(raw) - min(37, len(last.data))])
    rep = run_json(capsys, ["replay", str(cut), "--json"])
    assert rep["truncated_bytes"] > 0
    assert doc["frames"] - 2 <= rep["frames"] < doc["frames"]


@pytest.mark.parametrize(("perturb", "lo", "hi"), [(0.0, 0.0, 1e-4), (0.5, 0.49, 0.51)])
def test_replay_verify(tmp_path: Path, perturb: float, lo: float, hi: float,
                       capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = make_data(seconds=3.0, perturb_deg=perturb)
    rig_file = tmp_path / "rig.toml"
    rig_file.write_text(rig)
    with FakeDevice(data, tmp_path) as fake:
        out, _ = record(tmp_path, str(fake.path), rig_file, capsys, 1.0, 0, "--restart-filter")
    rep = run_json(capsys, ["replay", str(out), "--json", "--verify"])
    assert lo <= rep["max_abs_dtheta_deg"] <= hi
    assert lo <= rep["rms_dtheta_deg"] <= hi
    # Every frame from the restart on is verified; the few streamed between start_stream and
    # restart_filter belong to a filter run that began before the recording.
    (start,) = reset_frames(out)
    assert start < 20 and rep["unverified_frames"] == start
    assert rep["verified_frames"] == rep["messages"]["sample_estimate"] - start > 400
    assert rep["segments"] == 1


def test_replay_verify_refuses_a_recording_without_a_filter_start(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    with FakeDevice(fake_data[0], tmp_path) as fake:  # no restart: no reset frame
        out, _ = record(tmp_path, str(fake.path), rig_file, capsys, 0.5, 0,
                        "--no-restart-filter")
    assert reset_frames(out) == []
    capsys.readouterr()
    assert main(["replay", str(out), "--verify"]) == 2
    assert "no filter start (health 'reset')" in capsys.readouterr().err


def test_record_restarts_the_filter_by_default(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    # As live does: the recording then holds a filter start and replay --verify checks it.
    with FakeDevice(fake_data[0], tmp_path) as fake:
        out, _ = record(tmp_path, str(fake.path), rig_file, capsys, 0.5)
        assert "restart_filter" in fake.counts.commands
    assert len(reset_frames(out)) == 1
    rep = run_json(capsys, ["replay", str(out), "--json", "--verify"])
    assert rep["verified_frames"] > 0


def test_replay_verify_follows_filter_runs_across_gaps(tmp_path: Path, rig_file: Path,
                                                       fake_data: tuple[FakeData, str],
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # A frame lost at 100: mirror cannot follow past it; the fake's restart at 250 (set_filter
    # would do the same) starts a second verifiable run.
    data = fake_data[0]
    short = replace(data, counts=data.counts[:250], theta_q24=data.theta_q24[:250],
                    omega_a_q16=data.omega_a_q16[:250], omega_b_q16=data.omega_b_q16[:250])
    with FakeDevice(short, tmp_path, FakeFaults(drop=frozenset({100}))) as fake:
        out, _ = record(tmp_path, str(fake.path), rig_file, capsys, 1.0, 0, "--restart-filter")
    rep = run_json(capsys, ["replay", str(out), "--json", "--verify"])
    assert rep["segments"] >= 2
    # Unverifiable: the frames before the restart, and those from the one after the lost
    # stream frame 100 (recorded index 100) to the next start, when the table wraps.
    first, second = reset_frames(out)[:2]
    assert first < 20 and second == first + 249
    assert rep["unverified_frames"] == first + (second - 100)
    assert rep["max_abs_dtheta_deg"] < 1e-4


def test_replay_verify_without_a_rig(tmp_path: Path, fake_data: tuple[FakeData, str],
                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "norig.jrec"
    with FakeDevice(fake_data[0], tmp_path) as fake:
        assert main(["record", "--port", str(fake.path), "--seconds", "0.3", "--out",
                     str(out)]) == 0
    capsys.readouterr()
    assert main(["replay", str(out), "--verify"]) == 2
    assert "no 'rig' entry" in capsys.readouterr().err


def test_record_refuses_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 1\n")
    assert main(["record", "--port", "loop://", "--seconds", "1", "--out",
                 str(tmp_path / "x.jrec"), "--rig", str(bad)]) == 2
    assert "bad.toml" in capsys.readouterr().err
    assert main(["record", "--port", "loop://", "--seconds", "0", "--out",
                 str(tmp_path / "x.jrec")]) == 2
    assert "--seconds" in capsys.readouterr().err
    assert not (tmp_path / "x.jrec").exists()


def test_device_readings_match_the_float_path() -> None:
    """The firmware's Q15.16 readings agree with counts·LSB → link frame within one LSB."""
    from jointangle.device.calibration_map import DeviceMaps, device_readings, mps2_per_count
    from jointangle.estimators.base import sensor_to_link
    from jointangle.rig import LinkConfig
    from jointangle.sim.scenarios import gravity_rig

    rig = gravity_rig(500)
    s0 = replace(rig.links["a"].sensors[0], rotation_deg=30.0,
                 S=((1.01, 0.002, 0.0), (0.0, 0.99, 0.01), (0.0, 0.0, 1.0)),
                 offset=(0.05, -0.02, 0.1))
    rig = replace(rig, links={**rig.links, "a": LinkConfig(rig.links["a"].joint,
                                                           (s0, rig.links["a"].sensors[1]))})
    rng = np.random.default_rng(0)
    counts = rng.integers(-500, 500, size=(200, 4, 3))
    lsb = np.array([float(mps2_per_count(s.model, s.range_g))
                    for _, _, s in rig.all_sensors()])
    ref = sensor_to_link(rig, counts * lsb[None, :, None])
    got = device_readings(DeviceMaps.from_rig(rig), counts)
    assert np.max(np.abs(got - ref)) <= 1.5 / 65536
    assert np.all(got * 65536 == np.round(got * 65536))  # exact Q15.16 values


def test_ctrl_c_keeps_the_recording_valid(tmp_path: Path, fake_data: tuple[FakeData, str],
                                          rig_file: Path) -> None:
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "int.jrec"
    with FakeDevice(fake_data[0], tmp_path) as fake:
        proc = subprocess.Popen([sys.executable, "-m", "jointangle", "record", "--port",
                                 str(fake.path), "--seconds", "60", "--out", str(out), "--rig",
                                 str(rig_file), "--json"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)
        try:
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and (not out.exists() or
                                                   out.stat().st_size < 20_000):
                time.sleep(0.05)
            proc.send_signal(signal.SIGINT)
            stdout, _ = proc.communicate(timeout=15)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert "stop_stream" in fake.counts.commands  # stopped the stream on the way out
    assert proc.returncode == 130
    doc = json.loads(stdout)
    assert doc["interrupted"] and not doc["complete"] and doc["samples"] > 100
    rec = JrecReader.open(out)
    assert rec.truncated_bytes == 0
    assert JrecReader.open(out).metadata["rig"] == rig_file.read_text()


def test_info_text(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "--port", port]) == 0
    out = capsys.readouterr().out
    assert "jointangle firmware" in out and "matches this host" in out
    assert "sensor 0: link a" in out and "chip id 0x" in out


def test_record_into_a_directory_is_refused_before_connecting(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["record", "--port", "loop://", "--seconds", "1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "is a directory" in err and str(tmp_path) in err


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_term_and_hup_stop_the_virtual_board_and_keep_the_recording(
        tmp_path: Path, signame: str) -> None:
    # `kill`, `timeout` or a closed terminal: the host stops as on Ctrl-C, so the virtual board
    # it started is stopped too (it used to keep running) and the recording stays valid.
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "term.jrec"
    proc = subprocess.Popen([sys.executable, "-m", "jointangle", "record", "--port",
                             "sim://native", "--seconds", "60", "--out", str(out), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (not out.exists() or
                                               out.stat().st_size < 20_000):
            time.sleep(0.05)
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
        assert children, "the virtual board runs as a child of record"
        proc.send_signal(getattr(signal, signame))
        stdout, _ = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert json.loads(stdout)["interrupted"]
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and any(Path(f"/proc/{c}").exists() for c in children):
        time.sleep(0.05)
    assert not [c for c in children if Path(f"/proc/{c}").exists()], "the board outlived record"
    assert JrecReader.open(out).truncated_bytes == 0
