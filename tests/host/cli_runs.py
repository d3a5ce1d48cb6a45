"""The `jointangle` command run as a user runs it, for the tests: its input files made by
`simulate`, its one-line errors checked, and `live` run until the device clock passes a time."""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from jointangle.cli.main import main


def simulate_files(tmp_path_factory: pytest.TempPathFactory, name: str,
                   seconds: float) -> tuple[Path, Path]:
    """`seconds` of gravity-ramp as an accelerations CSV and its rig file, in a new folder."""
    d = tmp_path_factory.mktemp(name)
    data, rig = d / "data.csv", d / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", str(seconds), "--out",
                 str(data), "--rig-out", str(rig)]) == 0
    return data, rig


def one_line_error(err: str, *needles: str) -> None:
    """A bad-input error as the CLI must give it: one line, no traceback, naming `needles`."""
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


@dataclass
class LiveRun:
    rows: list[dict[str, Any]]  # one per estimate (`live --json-lines`)
    summary: dict[str, Any]  # `live --json`
    returncode: int
    stderr: str


def run_live(url: str, until_device_s: float, *extra: str, timeout_s: float | None = None,
             cwd: Path | None = None) -> LiveRun:
    """`jointangle live --port URL --json-lines --json [extra]` until the device clock passes
    `until_device_s` (whatever the board's speed), then Ctrl-C, as a user would. The time limit
    (default 60 s + 3 s per device second) only catches a board that stopped."""
    if timeout_s is None:
        timeout_s = 60.0 + 3.0 * until_device_s
    cmd = [sys.executable, "-m", "jointangle", "live", "--port", url, "--json-lines", "--json",
           "--seconds", str(timeout_s), "--timeout", "5", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=cwd)
    assert proc.stdout is not None
    lines: list[bytes] = []
    buf = b""
    deadline = time.monotonic() + timeout_s + 30
    try:
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            done = False
            while not done and time.monotonic() < deadline:
                if not sel.select(timeout=0.2):
                    if proc.poll() is not None:
                        break
                    continue
                chunk = os.read(proc.stdout.fileno(), 1 << 16)
                if not chunk:
                    break
                buf += chunk
                *new, buf = buf.split(b"\n")
                lines += new
                if new and b'"device_t"' in new[-1]:
                    done = json.loads(new[-1])["device_t"] >= until_device_s
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines += (buf + out).split(b"\n")
    docs = [json.loads(ln) for ln in lines if ln.strip()]
    rows = [d for d in docs if "device_t" in d]
    summaries = [d for d in docs if "device_t" not in d]
    assert summaries, f"live printed no summary (status {proc.returncode}): {err.decode()[-800:]}"
    return LiveRun(rows, summaries[-1], proc.returncode, err.decode(errors="replace"))
