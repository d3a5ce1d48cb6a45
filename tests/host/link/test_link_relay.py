"""The reliability acceptance of issue 16 with a real virtual board: a relay on a pty sits
between sim://native and `record` (or `live`) and damages the board's stream on the way --
random bytes between frames, a bad CRC, duplicated, swapped and stale frames, a valid frame of
another protocol version. `record --json`, `live --json` and `replay --json` of the recording
report exactly what was injected."""

from __future__ import annotations

import json
import os
import random
import select
import threading
import tty
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from fake_device import corrupt_frame

from jointangle.boards.launchers import NativeBoardLauncher
from jointangle.boards.options import LaunchOptions
from jointangle.cli.main import main
from jointangle.protocol import messages as msgs
from jointangle.protocol.framing import encode_frame
from jointangle.transport import open_port

STALE_AGE = 400  # frames back: beyond the host's reorder window


@dataclass
class Relay:
    """Copies bytes between the board's pty and a pty of its own (the host opens `path`),
    damaging board frames by ordinal (counted in `injected`)."""

    board: object  # transport.Connection
    faults: dict[int, str]
    path: Path = Path()
    injected: dict[str, int] = field(default_factory=dict)
    junk_bytes: int = 0
    _stop: threading.Event = field(default_factory=threading.Event)

    def start(self, link: Path) -> None:
        self._master, slave = os.openpty()
        tty.setraw(slave)
        self._slave = slave
        link.symlink_to(os.ttyname(slave))
        self.path = link
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5)
        os.close(self._master)
        os.close(self._slave)

    def _run(self) -> None:
        port = self.board.port  # type: ignore[attr-defined]
        rnd = random.Random(16)
        pending = b""
        history: list[bytes] = []
        held = b""  # a frame held back by "swap": it goes after the next one
        while not self._stop.is_set():
            r, _, _ = select.select([self._master], [], [], 0.001)
            if r:
                port.write(os.read(self._master, 4096))  # host -> board, untouched
            data = port.read(max(1, port.in_waiting))
            if not data:
                continue
            pending += data
            *bodies, pending = pending.split(b"\x00")
            out = bytearray()
            for body in bodies:
                frame = body + b"\x00"
                k = len(history)
                history.append(frame)
                kind = self.faults.get(k)
                chunk = frame
                if kind is not None:
                    self.injected[kind] = self.injected.get(kind, 0) + 1
                if kind == "junk":  # a short run of random bytes: one malformed chunk
                    junk = bytes(rnd.randrange(1, 256) for _ in range(rnd.randrange(3, 10)))
                    self.junk_bytes += len(junk)
                    chunk = frame + junk + b"\x00"
                elif kind == "crc":
                    chunk = corrupt_frame(frame)
                elif kind == "duplicate":
                    chunk = frame + frame
                elif kind == "swap":
                    held, chunk = frame, b""
                elif kind == "stale":
                    chunk = frame + history[k - STALE_AGE]
                elif kind == "version":
                    chunk = frame + encode_frame(msgs.Log.MSG_ID, 7, 0, b"\x01v2", version=2)
                elif held:
                    chunk, held = frame + held, b""
                out += chunk
            os.write(self._master, bytes(out))


FAULTS = {1000: "junk", 1500: "duplicate", 2000: "swap", 2500: "stale", 3000: "version",
          3500: "crc", 4000: "duplicate", 4500: "swap", 5000: "stale", 5500: "junk"}


def _through_relay(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                   argv: list[str]) -> tuple[dict, dict[str, int]]:
    """Run `jointangle ARGV --port RELAY` against a fresh sim://native behind a relay."""
    NativeBoardLauncher().find_binary(build=False)  # fails with how to build it
    board = open_port("sim://native?fast=1", launch=LaunchOptions(start_timeout_s=60))
    relay = Relay(board, FAULTS)
    relay.start(tmp_path / f"relay-{argv[0]}")
    try:
        capsys.readouterr()
        assert main([argv[0], "--port", str(relay.path), *argv[1:]]) == 0
        doc = json.loads(capsys.readouterr().out.splitlines()[-1])
    finally:
        relay.stop()
        board.close()
    assert doc["frames"] > 6000, "the board streamed too little to reach every fault"
    return doc, relay.injected


def test_a_damaged_link_is_counted_exactly(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.jrec"
    rec, injected = _through_relay(tmp_path, capsys, ["record", "--seconds", "3", "--out",
                                                      str(out), "--json", "--host-filter",
                                                      "none"])
    assert injected == {"junk": 2, "duplicate": 2, "swap": 2, "stale": 2, "version": 1,
                        "crc": 1}
    live, _ = _through_relay(tmp_path, capsys, ["live", "--seconds", "3", "--json"])
    capsys.readouterr()
    assert main(["replay", str(out), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    for doc in (rec, live, rep):
        assert doc["frames_lost"] == 1, doc  # the CRC-damaged frame never arrived
        assert (doc["duplicates"], doc["out_of_order"], doc["stale"]) == (2, 2, 2), doc
        assert (doc["version_errors"], doc["crc_errors"], doc["malformed"]) == (1, 1, 2), doc
        assert doc["segments"] == 1
    for key in ("frames", "frames_lost", "duplicates", "out_of_order", "stale", "crc_errors",
                "version_errors", "malformed", "bytes_skipped"):
        assert rec[key] == rep[key], key
