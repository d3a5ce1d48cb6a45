"""HIL: the serial link's losses, as a user sees them (docs/design.md §6, issue 5 acceptance).

- At a deliberately too-low baud rate the board's UART drops whole frames and counts them
  (status `uart_drops`); the host counts the sequence gaps (`frames_lost`); live shows both.
- A pulled cable: the recording stays valid to its last byte (every frame the board sent before
  the cut is in it), and with the cable plugged back in the host reconnects by itself.

Runs against every virtual board (conftest.hil_port); the baud rate and the cable pull are set
through the sim:// URL (`baud=`, `disconnect=S` simulated seconds, `reconnect=S` later).
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from cli_runs import LiveRun

from jointangle.cli.main import main
from jointangle.protocol import messages as msgs
from jointangle.protocol.framing import StreamDecoder
from jointangle.recording.jrec import JrecReader

FRAME_BYTES_MIN = 60  # a 4-sensor sample_estimate frame on the wire is ~70 bytes (COBS + 0x00)
TOO_LOW_BAUD = 115_200  # too slow for every board's stream (test_too_low_baud_rate_...)


def run_json(capsys: pytest.CaptureFixture[str], argv: list[str], code: int = 0) -> dict:
    capsys.readouterr()
    assert main(argv) == code
    return json.loads(capsys.readouterr().out)


def sample_times(rec: Path) -> list[float]:
    """Device time (s) of every sample_estimate frame in a recording, in order."""
    dec = StreamDecoder()
    return [fr.t_us / 1e6 for ch in JrecReader.open(rec).chunks() for fr in dec.feed(ch.data)
            if fr.msg_id == msgs.SampleEstimate.MSG_ID]


def test_too_low_baud_rate_drops_are_counted_and_shown(
        sim_url: Callable[..., str], live_until: Callable[..., LiveRun], tmp_path: Path) -> None:
    # 500 frames/s of ~70 bytes need ~350 kbaud (10 bits a byte), the 250 a Mega sends when
    # asked for 500 Hz (it loops every other slot) ~175 kbaud; 115 200 baud carries ~11.5 kB/s.
    baud = TOO_LOW_BAUD
    rec = tmp_path / "slow.jrec"
    run = live_until(sim_url(fast=1, baud=baud), 3.0, "--record", str(rec))
    s = run.summary
    sent = s["frames"] + s["frames_lost"]
    print(f"\n{baud} baud: {s['frames']} frames received, {s['frames_lost']} lost "
          f"({100 * s['frame_loss']:.1f} %), last status: uart_drops {s['uart_drops']} bytes, "
          f"{s['status_age_s']} s old; {s['crc_errors']} CRC errors")
    assert s["frames_lost"] > 0.2 * sent, s  # counted by the host (sequence gaps)
    assert s["crc_errors"] == 0, s  # whole frames are dropped, never half a frame
    assert s["sample_rate_hz"] < 0.8 * 500, s  # what arrives is what the line carries
    # What arrived fits the line: bytes per device second <= baud / 10.
    t = sample_times(rec)
    assert len(t) * FRAME_BYTES_MIN / (t[-1] - t[0]) <= baud / 10
    # The live view shows the loss, and the board's drop counter or that it has not heard it.
    view = view_of_recording(rec)
    assert f"lost {s['frames_lost']} (" in view, view
    drops = s["uart_drops"] or 0
    assert (drops > 0 and f"UART drops {drops}" in view) or "no status frame for" in view, view


def view_of_recording(rec: Path) -> str:
    """The rich live view (80 columns) after every frame of a `live --record` recording."""
    from rich.console import Console

    from jointangle.live.session import LiveState
    from jointangle.live.view import render
    from jointangle.protocol.bulk import bulk_decode
    from jointangle.recording.export import find_hello

    r = JrecReader.open(rec)
    hello = find_hello(bulk_decode(r.data()), r.metadata)
    assert hello is not None
    state = LiveState(hello, None)
    dec = StreamDecoder()
    for ch in r.chunks():
        state.feed(dec.feed(ch.data))
    console = Console(width=80, record=True, file=io.StringIO())
    console.print(render(state, port="hil", stats=dec.stats.as_dict(), interactive=False))
    return console.export_text()


def test_the_board_counts_its_uart_drops(sim_url: Callable[..., str]) -> None:
    """Through the protocol: stream at a too-low baud rate, then ask for status only (the line
    clears): the status frames report the bytes the transmit buffer dropped."""
    from jointangle.boards.options import LaunchOptions
    from jointangle.protocol.codec import decode_message
    from jointangle.protocol.link import Link
    from jointangle.transport import open_port

    with open_port(sim_url(fast=1, baud=TOO_LOW_BAUD),
                   launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10)
        link.handshake()
        link.command(msgs.StartStream(mode=msgs.StreamMode.SAMPLE_ESTIMATE, status_interval_ms=0))
        dec_seq: list[int] = []
        while len(dec_seq) < 600:
            dec_seq += [fr.seq for fr in link.poll()
                        if fr.msg_id == msgs.SampleEstimate.MSG_ID]
        gaps = sum((b - a - 1) & 0xFFFF for a, b in pairwise(dec_seq))
        link.command(msgs.StartStream(mode=msgs.StreamMode.STATUS, status_interval_ms=100))
        status = None
        for _ in range(10):
            fr = link.wait_for(msgs.Status.MSG_ID)
            msg = decode_message(fr)
            assert isinstance(msg, msgs.Status)
            status = msg
            if status.uart_drops:
                break
        link.command(msgs.StopStream())
    assert gaps > 100, gaps
    assert status is not None and status.uart_drops >= min(65535, gaps * FRAME_BYTES_MIN), \
        (status, gaps)


def test_recording_is_valid_to_its_last_byte_after_a_pulled_cable(
        sim_url: Callable[..., str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    cut_s = 1.0
    out = tmp_path / "cut.jrec"
    doc = run_json(capsys, ["record", "--port", sim_url(fast=1, disconnect=cut_s), "--seconds",
                            "30", "--out", str(out), "--retries", "2", "--retry-delay", "0.2",
                            "--timeout", "5", "--json"], code=1)
    assert doc["disconnects"] == 1 and doc["reconnects"] == 0 and not doc["complete"]
    assert "did not come back" in doc["error"]
    rep = run_json(capsys, ["replay", str(out), "--json"])
    assert rep["truncated_bytes"] == 0 and rep["pending_bytes"] == 0  # closed cleanly
    assert rep["frames"] == doc["frames"] and rep["frames_lost"] == 0 == rep["crc_errors"]
    # Everything the board sent before the cut arrived and was kept: the stream runs to it.
    t = sample_times(out)
    assert t[-1] >= cut_s - 0.01 and t[-1] <= cut_s + 0.05, t[-3:]


def test_host_reconnects_by_itself(sim_url: Callable[..., str], tmp_path: Path,
                                   live_until: Callable[..., LiveRun],
                                   capsys: pytest.CaptureFixture[str]) -> None:
    url = sim_url(fast=1, disconnect=1.0, reconnect=0.3)
    out = tmp_path / "re.jrec"
    doc = run_json(capsys, ["record", "--port", url, "--seconds", "3", "--out", str(out),
                            "--retry-delay", "0.2", "--timeout", "5", "--json"])
    assert doc["complete"] and doc["disconnects"] == 1 and doc["reconnects"] == 1, doc
    rep = run_json(capsys, ["replay", str(out), "--json"])
    assert rep["frames"] == doc["frames"] and rep["crc_errors"] == 0
    assert rep["truncated_bytes"] == 0 and rep["messages"]["hello"] >= 2
    # The frames the board sent while the cable was out are lost, and record counts them as
    # replay does over the whole file (before, record's count restarted with the new link: 0).
    assert rep["frames_lost"] > 0 and doc["frames_lost"] == rep["frames_lost"], (doc, rep)
    # Samples from before the cut (at 1.0 s) and after the reconnect: the longest gap in the
    # device times is the cable pull, with samples on both sides of it. (How far past it the
    # recording reaches depends on the board's speed: a real-time one, the Pico emulator, gets
    # ~0.2 s of device time into record's 3 s after the pull and the host's retry.)
    t = sample_times(out)
    gap = int(np.argmax(np.diff(t)))
    assert t[0] < 1.0 <= t[gap + 1] < t[-1], (t[0], t[gap], t[gap + 1], t[-1])
    assert t[gap + 1] - t[gap] > 5 * (t[1] - t[0]), (t[gap], t[gap + 1])
    # live does the same and keeps streaming.
    run = live_until(url, 4.0)
    s = run.summary
    assert s["disconnects"] == 1 and s["reconnects"] == 1, s
    assert run.rows[-1]["device_t"] >= 4.0
