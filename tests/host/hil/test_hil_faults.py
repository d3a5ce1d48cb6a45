"""HIL: each injected sensor fault shows up as its documented status flag (firmware/app/APP.md,
"Faults") in the stream, in `jointangle live --json-lines` and in the live view, and streaming
continues through it (docs/design.md §6). Runs against every virtual board (conftest.hil_port); the
fault is set through the sim:// URL, e.g. `sim://native?fast=1&fault=a.1:nack@1-2`.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable
from pathlib import Path

import pytest
from cli_runs import LiveRun

from jointangle.protocol.framing import Frame, StreamDecoder
from jointangle.recording.jrec import JrecReader

START_S, END_S = 1.0, 2.0  # the fault's window, simulated seconds
# How long after the fault starts the flag may take, and after it ends its clearing may take
# (APP.md): the ID check visits one working sensor per 100 ms (4 sensors), frozen needs 0.2 s
# of unchanged output, and a faulted sensor is re-probed (flags cleared) one per 250 ms.
ONSET_S = {"nack": 0.05, "wrong_id": 0.45, "saturate": 0.05, "frozen": 0.3}
CLEAR_S = 0.6
END_SLACK_S = 0.005
FLAG = {"nack": "nack", "wrong_id": "wrong_id", "saturate": "saturated", "frozen": "frozen"}
COUNTER = {"nack": "nacks", "wrong_id": "id_errors", "saturate": "saturations",
           "frozen": "freezes"}  # status frame, per sensor
SENSOR, VIEW_NAME = "a.1", "a1"  # second sensor of link a: index 1 in rig order


def view_text(rec_path: Path, until_device_s: float) -> str:
    """The rich live view (80 columns) as it looked when the device clock reached
    `until_device_s`, rebuilt from the frames `live --record` kept."""
    from rich.console import Console

    from jointangle.live.session import LiveState
    from jointangle.live.view import render
    from jointangle.protocol.bulk import bulk_decode
    from jointangle.recording.export import find_hello

    rec = JrecReader.open(rec_path)
    hello = find_hello(bulk_decode(rec.data()), rec.metadata)
    assert hello is not None
    state = LiveState(hello, None)
    dec = StreamDecoder()
    frames: list[Frame] = [fr for ch in rec.chunks() for fr in dec.feed(ch.data)]
    for fr in frames:
        state.feed([fr])
        if state.latest is not None and state.latest.device_s >= until_device_s:
            break
    console = Console(width=80, record=True, file=io.StringIO())
    console.print(render(state, port="hil", stats={}, interactive=False))
    return console.export_text()


@pytest.mark.parametrize("kind", ["nack", "wrong_id", "saturate", "frozen"])
def test_sensor_fault_is_flagged_and_streaming_continues(
        kind: str, sim_url: Callable[..., str], live_until: Callable[..., LiveRun],
        tmp_path: Path) -> None:
    rec = tmp_path / "fault.jrec"
    url = sim_url(f"{SENSOR}:{kind}@{START_S}-{END_S}", fast=1)
    run = live_until(url, END_S + 1.5, "--record", str(rec))
    flag = FLAG[kind]
    k = int(SENSOR[2]) + (0 if SENSOR[0] == "a" else 2)
    rows = run.rows
    assert rows and rows[-1]["device_t"] >= END_S + 1.5, (run.returncode, run.stderr[-500:])

    def flagged(r: dict) -> bool:
        return flag in r["sensors"][k]

    before = [r for r in rows if r["device_t"] < START_S]
    # The device clock trails simulated time by its boot (and frames carry samples read one
    # period earlier): a frame stamped in the last few ms before END_S may see the fault cleared.
    during = [r for r in rows if START_S + ONSET_S[kind] <= r["device_t"] < END_S - END_SLACK_S]
    after = [r for r in rows if r["device_t"] >= END_S + CLEAR_S]
    assert before and during and after
    assert not any(flagged(r) for r in before)
    assert all(flagged(r) for r in during), next(r for r in during if not flagged(r))
    assert not any(flagged(r) for r in after)
    # Only that sensor: the others stay clean throughout.
    others = {f for r in rows for i, s in enumerate(r["sensors"]) if i != k for f in s}
    assert not others & set(FLAG.values()), others
    # A faulted sensor is not used: with one usable sensor left on link a the filter stops
    # (its θ means nothing, health lacks running), and runs again once the fault has cleared.
    assert not any("running" in r["health"] for r in during)
    assert all(r["theta_deg"] is None and r["omega_a_dps"] is None for r in during)  # not 0°
    assert all("running" in r["health"] for r in after)
    # Streaming continued: nothing lost, no damage, the stream reached past the fault.
    s = run.summary
    assert s["frames_lost"] == 0 and s["crc_errors"] == 0 and s["uart_drops"] == 0, s
    assert s["sensors"][k] == [] and s["disconnects"] == 0
    # The board counted it (status frames): this sensor's counter, and no other's.
    counters = s["sensor_counters"]
    assert counters[k][COUNTER[kind]] > 0, counters
    assert all(v == 0 for i, c in enumerate(counters) if i != k for v in c.values()), counters
    # The live view said so while it lasted, and is clean again afterwards.
    mid = view_text(rec, (START_S + ONSET_S[kind] + END_S) / 2)
    assert f"{VIEW_NAME} {flag}" in mid, mid
    assert "θ and ω mean nothing" in mid, mid
    late = view_text(rec, END_S + 1.2)
    assert f"{VIEW_NAME} ok" in late and flag not in late, late


def test_fault_in_the_interactive_view_80x24(sim_url: Callable[..., str], tmp_path: Path) -> None:
    """The real terminal view (tmux, 80×24), real time: the fault appears on screen while the
    angle keeps updating, and q still quits with status 0."""
    import shlex
    import shutil
    import subprocess
    import sys
    import time
    import uuid

    assert shutil.which("tmux"), "tmux is missing (scripts/setup.sh installs it)"
    session = f"ja-hil-{uuid.uuid4().hex[:8]}"
    jointangle = Path(sys.executable).with_name("jointangle")
    done = tmp_path / "exit_status"
    url = sim_url("a.1:saturate@1")
    # A tmux server started earlier has its own environment: pass ours ($JOINTANGLE_*) along.
    env = " ".join(f"{k}={shlex.quote(v)}" for k, v in os.environ.items()
                   if k.startswith("JOINTANGLE_"))
    cmd = (f"cd {tmp_path} && env {env} {jointangle} live --port {shlex.quote(url)}; "
           f"echo $? > {done}")
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "80", "-y", "24", cmd],
                   check=True)

    def screen() -> str:
        return subprocess.run(["tmux", "capture-pane", "-t", session, "-p"], check=True,
                              capture_output=True, text=True).stdout

    try:
        shot = ""
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and "a1 saturated" not in shot:
            time.sleep(0.3)
            shot = screen()
        lines = shot.splitlines()
        assert "a1 saturated" in shot and "a0 ok" in shot and "b1 ok" in shot, shot
        assert len(lines) <= 24 and all(len(ln) <= 80 for ln in lines), shot
        assert "θ and ω mean nothing" in shot, shot  # link a has one usable sensor left
        subprocess.run(["tmux", "send-keys", "-t", session, "q"], check=True)
        deadline = time.monotonic() + 20
        while not done.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert done.exists() and done.read_text().strip() == "0"
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)
