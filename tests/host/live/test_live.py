"""`jointangle live`: JSON lines, the non-interactive run, the 80×24 view, keys in a terminal.

Runs against the fake device on a pty (fake_device.py) and, when $JOINTANGLE_TEST_PORT names
one, a real port or virtual board (the tests that need the fake's data use the fake only).
"""

from __future__ import annotations

import fcntl
import io
import itertools
import json
import os
import pty
import select
import struct
import subprocess
import sys
import termios
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fake_device import FakeData, FakeDevice, FakeFaults, make_data
from rich.console import Console

from jointangle.cli.main import main
from jointangle.live.session import LiveState
from jointangle.live.view import render
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import encode_message
from jointangle.protocol.framing import decode_stream
from jointangle.recording.jrec import JrecReader


def test_live_json_lines(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--port", port, "--json-lines", "--seconds", "1"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(rows) > 200
    assert {"t", "seq", "theta_deg", "omega_a_dps", "omega_b_dps", "health",
            "sensors"} <= set(rows[0])
    assert all(b["t"] > a["t"] for a, b in itertools.pairwise(rows))
    assert "running" in rows[-1]["health"]


@pytest.mark.parametrize(("perturb", "lo", "hi"), [(0.0, 0.0, 1e-4), (0.5, 0.49, 0.51)])
def test_live_non_interactive_divergence(tmp_path: Path, perturb: float, lo: float, hi: float,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = make_data(seconds=3.0, perturb_deg=perturb)
    (tmp_path / "rig.toml").write_text(rig)
    with FakeDevice(data, tmp_path) as fake:
        assert main(["live", "--port", str(fake.path), "--rig", str(tmp_path / "rig.toml"),
                     "--seconds", "1", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["samples"] > 300 and s["frames_lost"] == 0 and s["filter_runs"] == 1
    assert lo <= s["max_abs_dtheta_deg"] <= hi and s["dtheta_frames"] > 300
    assert 350 < s["sample_rate_hz"] < 650
    assert s["observable"] is True and s["sensors"] == [[], [], [], []]


def test_live_text_lines_when_not_a_terminal(port: str, rig_file: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--port", port, "--seconds", "1.5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) >= 2 and "θ" in lines[-1] and "Hz" in lines[-1]


def test_live_shows_faults_losses_and_unobservable(tmp_path: Path,
                                                   fake_data: tuple[FakeData, str],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = fake_data
    n = len(data.counts)
    # At rest with the hinge vertical: gravity only on z, nothing in the plane.
    still = np.zeros_like(data.counts)
    still[:, :, 2] = 256
    status = np.zeros((n, 4), dtype=np.int64)
    status[100:, 2] = msgs.SensorStatus.FROZEN
    data = replace(data, counts=still, sensor_status=status)
    (tmp_path / "rig.toml").write_text(rig)
    with FakeDevice(data, tmp_path, FakeFaults(drop=frozenset({30, 31}))) as fake:
        assert main(["live", "--port", str(fake.path), "--rig", str(tmp_path / "rig.toml"),
                     "--seconds", "0.8", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["frames_lost"] == 2 and s["frame_loss"] > 0
    assert "frozen" in s["sensors"][2] and s["sensors"][0] == []
    assert s["observable"] is False


def test_live_plot_needs_a_display(monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["live", "--port", "loop://", "--plot"]) == 2
    assert "--plot needs a display" in capsys.readouterr().err


def _state(fake_data: tuple[FakeData, str], frames: int, observable: bool | None) -> LiveState:
    from jointangle.device.rig import device_rig
    from jointangle.rig import parse_rig

    data, rig_text = fake_data
    hello = msgs.Hello(1, msgs.SCHEMA_HASH, 0, 9, 1, b"fake", msgs.Board.NATIVE, data.rate_hz,
                       4, 0, data.sensors)
    state = LiveState(hello, device_rig(parse_rig(rig_text), hello))
    def wire(k: int, frozen: int) -> bytes:
        health = msgs.FilterHealth.RUNNING | (msgs.FilterHealth.RESET if k == 0 else 0)
        msg = msgs.SampleEstimate(int(data.theta_q24[k]), 0, 0, int(health), tuple(
            msgs.SampleEstimateSensor(*map(int, c), 1, frozen if i == 3 else 0)
            for i, c in enumerate(data.counts[k])))
        return encode_message(msg, k, 2000 * k)

    state.feed(decode_stream(b"".join(wire(k, 0) for k in range(frames)))[0])
    state.refresh()
    if state.worker is not None:
        state.worker.wait()
    if frames:  # then sensor b1 freezes: the firmware's filter changes sensors
        state.feed(decode_stream(wire(frames, msgs.SensorStatus.FROZEN))[0])
    state.observable = observable
    return state


def test_view_fits_80x24(fake_data: tuple[FakeData, str]) -> None:
    state = _state(fake_data, 600, observable=False)
    buf = io.StringIO()
    console = Console(file=buf, width=80, height=24, force_terminal=True, color_system=None)
    console.print(render(state, port="/dev/pts/7", recording="x.jrec", rec_seconds=3.0,
                         stats={"frames": 600, "frames_lost": 2, "crc_errors": 1},
                         message="device lost (port error); reconnecting"))
    lines = buf.getvalue().splitlines()
    assert len(lines) <= 24
    assert all(console.measure(line).maximum <= 80 for line in lines)
    text = buf.getvalue()
    for want in ("θ", "ω_a", "firmware − mirror: max |Δθ|", "b1 frozen", "not observable",
                 "lost 2", "REC x.jrec", "rate", "stopped: sensor choice changed"):
        assert want in text, want


def test_view_warns_of_a_board_that_misses_its_periods(fake_data: tuple[FakeData, str]) -> None:
    state = _state(fake_data, 600, observable=True)
    status = msgs.Status(uptime_ms=5000, loop_overruns=1234, uart_drops=0, loop_rate_hz=252,
                         idle_permille=0, eeprom=msgs.EepromState.OK, stream_mode=0,
                         rx_errors=0, sensors=())

    def text() -> str:
        buf = io.StringIO()
        console = Console(file=buf, width=80, height=24, force_terminal=True, color_system=None)
        console.print(render(state, port="p", stats={"frames": 600, "frames_lost": 2}))
        lines = buf.getvalue().splitlines()
        assert len(lines) <= 24 and all(console.measure(ln).maximum <= 80 for ln in lines)
        return buf.getvalue()

    state.status = status
    assert "board loop 252 of 500 Hz: 1234 periods missed; lower rate_hz" in text()
    # With its idle time the board says what it can hold: 250 Hz at 36.1 % asleep (the Mega
    # with four ADXL345 asked for 500 Hz in live) fits ~391 loops a second: 0.87 of it is 340.
    state.status = replace(status, loop_rate_hz=250, idle_permille=361)
    assert "board loop 250 of 500 Hz: 1234 periods missed; lower rate_hz to ≤ 340 Hz" in text()
    assert state.summary({})["board_sustainable_rate_hz"] == 340
    state.status = replace(status, loop_rate_hz=500, loop_overruns=0, idle_permille=200)
    assert "periods missed" not in text()
    summary = state.summary({})
    assert (summary["loop_overruns"], summary["board_loop_rate_hz"]) == (0, 500)
    assert summary["board_idle_fraction"] == 0.2 and summary["board_sustainable_rate_hz"] == 540


@pytest.mark.parametrize(("rate", "idle", "want"), [
    (250, 361, 340), (250, 281, 300), (340, 130, 340), (300, 249, 340), (500, 0, 430),
    (0, 500, None), (300, 1000, None)])
def test_sustainable_rate_from_the_boards_own_idle_time(rate: int, idle: int,
                                                        want: int | None) -> None:
    from jointangle.device.describe import sustainable_rate_hz
    st = msgs.Status(uptime_ms=1, loop_overruns=0, uart_drops=0, loop_rate_hz=rate,
                     idle_permille=idle, eeprom=msgs.EepromState.OK, stream_mode=0,
                     rx_errors=0, sensors=())
    assert sustainable_rate_hz(st) == want


def test_view_before_any_estimate(fake_data: tuple[FakeData, str]) -> None:
    state = _state(fake_data, 0, observable=None)
    buf = io.StringIO()
    Console(file=buf, width=80, color_system=None).print(render(state, port="p"))
    assert "waiting for estimates" in buf.getvalue()


def _read_until(fd: int, deadline: float, want: bytes | None = None) -> bytes:
    out = b""
    while time.monotonic() < deadline:
        if select.select([fd], [], [], 0.05)[0]:
            try:
                chunk = os.read(fd, 65536)
            except OSError:
                break
            if not chunk:
                break
            out += chunk
            if want is not None and want in out:
                break
    return out


def test_live_in_a_terminal_records_on_r_and_quits_on_q(tmp_path: Path,
                                                        fake_data: tuple[FakeData, str],
                                                        rig_file: Path) -> None:
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    env = {**os.environ, "COLUMNS": "80", "LINES": "24", "TERM": "xterm"}
    with FakeDevice(fake_data[0], tmp_path) as fake:
        proc = subprocess.Popen(
            [sys.executable, "-m", "jointangle", "live", "--port", str(fake.path), "--rig",
             str(rig_file), "--record-dir", str(tmp_path)],
            stdin=slave, stdout=slave, stderr=slave, env=env, close_fds=True)
        os.close(slave)
        try:
            screen = _read_until(master, time.monotonic() + 20, b"firmware")
            os.write(master, b"r")
            screen += _read_until(master, time.monotonic() + 1.0)
            os.write(master, b"r")
            screen += _read_until(master, time.monotonic() + 0.3)
            os.write(master, b"q")
            assert proc.wait(15) == 0
            screen += _read_until(master, time.monotonic() + 0.5)
        finally:
            if proc.poll() is None:
                proc.kill()
            os.close(master)
    text = screen.decode(errors="replace")
    assert "θ" in text and "r start/stop recording" in text
    recs = list(tmp_path.glob("jointangle-*.jrec"))
    assert len(recs) == 1
    rec = JrecReader.open(recs[0])
    assert rec.metadata["rig"] == rig_file.read_text() and len(rec.records) > 10


def test_live_reconnects_after_a_pulled_cable(tmp_path: Path, fake_data: tuple[FakeData, str],
                                              capsys: pytest.CaptureFixture[str]) -> None:
    faults = FakeFaults(disconnect_after=150, reconnect_after_s=0.2)
    with FakeDevice(fake_data[0], tmp_path, faults) as fake:
        assert main(["live", "--port", str(fake.path), "--seconds", "1.5", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["disconnects"] == 1 and s["reconnects"] == 1 and s["samples"] > 300


def test_sim_native_end_to_end_with_a_stand_in_board(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """sim://native through the real launcher: the stand-in (fake_device.serve_board) gets the
    rig and the motion CSV, announces its pty; live and record take the board's rig, and
    replay --verify checks the recording against mirror."""
    exe = tmp_path / "ja_native_board"
    host_tests = Path(__file__).resolve().parents[1]  # where fake_device.py is
    # The stand-in plays its first 3 s once: the launcher's --loop-motion does not apply.
    exe.write_text(f"#!{sys.executable}\nimport sys\nsys.path.insert(0, {str(host_tests)!r})\n"
                   "import fake_device\nargs = [a for a in sys.argv[1:] if a != '--loop-motion']\n"
                   "sys.exit(fake_device.serve_board(args))\n")
    exe.chmod(0o755)
    monkeypatch.setenv("JOINTANGLE_NATIVE_BOARD", str(exe))
    sim = ["--port", "sim://native", "--sim-seconds", "4", "--timeout", "3"]
    assert main(["live", *sim, "--seconds", "1.0", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["port"] == "sim://native" and s["samples"] > 200
    assert s["max_abs_dtheta_deg"] < 1e-4 and s["observable"] is True
    out = tmp_path / "sim.jrec"
    assert main(["record", *sim, "--seconds", "0.8", "--out", str(out), "--restart-filter",
                 "--json"]) == 0
    capsys.readouterr()
    assert main(["replay", str(out), "--verify", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["max_abs_dtheta_deg"] < 1e-4 and rep["verified_frames"] > 200


def test_live_on_a_virtual_board_follows_the_filter_from_its_start(
        capsys: pytest.CaptureFixture[str]) -> None:
    # The board's filter runs from boot, before the stream starts: by default live restarts
    # it on a board it started itself, so the divergence is there from the first second.
    assert main(["live", "--port", "sim://native?fast=1", "--seconds", "1.5", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["filter_runs"] >= 1
    assert summary["dtheta_frames"] > 0
    assert summary["max_abs_dtheta_deg"] is not None and summary["max_abs_dtheta_deg"] < 0.05


@pytest.mark.parametrize(("option", "sent"), [((), True), (("--no-restart-filter",), False)])
def test_live_restarts_the_filter_of_any_board_unless_told_not_to(
        tmp_path: Path, option: tuple[str, ...], sent: bool,
        capsys: pytest.CaptureFixture[str]) -> None:
    # restart_filter keeps the board's settings, so live sends it to a real port too (the fake
    # device is one: a pty path), and the divergence follows the filter from that frame.
    data, rig = make_data(seconds=3.0)
    (tmp_path / "rig.toml").write_text(rig)
    with FakeDevice(data, tmp_path) as fake:
        assert main(["live", "--port", str(fake.path), "--rig", str(tmp_path / "rig.toml"),
                     "--seconds", "0.5", "--json", *option]) == 0
        commands = list(fake.counts.commands)
    capsys.readouterr()
    assert ("restart_filter" in commands) == sent
    assert "set_filter" not in commands


def test_live_json_lines_into_a_closed_pipe_ends_quietly() -> None:
    # `jointangle live --json-lines | head -1` (README): the reader leaves, live stops with
    # status 0 and no traceback.
    exe = Path(sys.executable).with_name("jointangle")
    proc = subprocess.run(f"'{exe}' live --port 'sim://native?fast=1' --json-lines --seconds 5"
                          " | head -1", shell=True, capture_output=True, text=True, timeout=60,
                          check=False, executable="/bin/bash")
    assert json.loads(proc.stdout.strip())["theta_deg"] is not None
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr


def test_live_warns_and_streams_when_the_board_fell_back_to_defaults(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A bad EEPROM checksum puts the board on its defaults (ADXL345 at ±4 g), which no longer
    # match the scenario's rig: live says so and shows the stream without the divergence.
    eeprom = tmp_path / "ee.bin"
    url = f"sim://native?fast=1&eeprom={eeprom}"
    assert main(["info", "--port", url]) == 0
    data = bytearray(eeprom.read_bytes())
    data[10] ^= 0xFF
    eeprom.write_bytes(bytes(data))
    capsys.readouterr()
    assert main(["live", "--port", url, "--seconds", "1", "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["samples"] > 0 and summary["max_abs_dtheta_deg"] is None
    assert "rig not used" in captured.err and "±4 g" in captured.err


def test_a_lost_device_is_one_line_on_stderr_not_in_the_json_lines(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--port", "sim://native?fast=1&disconnect=1", "--json-lines",
                 "--seconds", "20"]) == 1
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    assert lines and all(json.loads(line) for line in lines)  # stdout is JSON only
    assert "did not come back" in cap.err and "\n" not in cap.err.strip()


def test_each_r_press_gets_its_own_recording_name(tmp_path: Path) -> None:
    # Two presses within a second used to name the same file, and the second ended live.
    from jointangle.cli.live import _new_recording_path

    first = _new_recording_path(tmp_path)
    first.write_bytes(b"")
    second = _new_recording_path(tmp_path)
    second.write_bytes(b"")
    third = _new_recording_path(tmp_path)
    assert len({first, second, third}) == 3 and not third.exists()
    assert all(p.parent == tmp_path and p.suffix == ".jrec" for p in (first, second, third))
