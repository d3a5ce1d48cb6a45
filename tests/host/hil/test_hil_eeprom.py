"""HIL: the configuration survives a virtual reset through EEPROM, and a corrupted EEPROM image
makes the board fall back to defaults and the host say so (docs/design.md §6,
APP.md "EEPROM image").
Runs against every virtual board (conftest.hil_port) through the protocol over pyserial and the
`jointangle info` command. `eeprom=FILE` in the sim:// URL names the board's EEPROM: a raw
image of its bytes, address 0 first, kept across runs.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from itertools import pairwise
from pathlib import Path

import pytest

from jointangle.boards.options import LaunchOptions
from jointangle.cli.main import main
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.link import Link
from jointangle.transport import open_port

TIMEOUT_S = 10.0  # per answer; save_eeprom takes ~2 s on the AVR (APP.md)
def factory_rate(url: str) -> int:
    """What a fresh EEPROM boots at on the board of `url`: a rate it holds with its factory
    sensors (its launcher's factory_rate_hz, the board's own constant)."""
    from urllib.parse import urlparse

    from jointangle.boards.launchers import SIM_LAUNCHERS

    return int(SIM_LAUNCHERS[urlparse(url).netloc].factory_rate_hz)  # type: ignore[attr-defined]


@contextmanager
def board(url: str) -> Iterator[tuple[Link, msgs.Hello]]:
    with open_port(url, launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=TIMEOUT_S)
        yield link, link.handshake()


def hello_after_reset(link: Link) -> msgs.Hello:
    """reset (reboot): ack, then the firmware starts again and says hello by itself."""
    # Frames from before (e.g. the get_info hello after the boot hello the handshake took)
    # were all sent before the last ack the caller waited for: drop them.
    link.poll()
    link.command(msgs.Reset(kind=msgs.ResetKind.REBOOT))
    # The hello may have come in the same read as the ack (Link keeps those for poll()).
    early = [fr for fr in link.poll() if fr.msg_id == msgs.Hello.MSG_ID]
    hello = decode_message(early[0] if early else link.wait_for(msgs.Hello.MSG_ID))
    assert isinstance(hello, msgs.Hello)
    return hello


def stream(link: Link, n: int) -> list[tuple[int, msgs.SampleEstimate]]:
    """n sample_estimate frames as (t_us, message)."""
    link.command(msgs.StartStream(mode=msgs.StreamMode.SAMPLE_ESTIMATE, status_interval_ms=0))
    out: list[tuple[int, msgs.SampleEstimate]] = []
    deadline = time.monotonic() + TIMEOUT_S
    while len(out) < n and time.monotonic() < deadline:
        for fr in link.poll():  # every frame, in order (poll also returns the held-back ones)
            if fr.msg_id == msgs.SampleEstimate.MSG_ID:
                msg = decode_message(fr)
                assert isinstance(msg, msgs.SampleEstimate)
                out.append((fr.t_us, msg))
    assert len(out) >= n, f"{len(out)} sample_estimate frames in {TIMEOUT_S} s"
    link.command(msgs.StopStream())
    return out


def info_json(capsys: pytest.CaptureFixture[str], url: str) -> dict:
    capsys.readouterr()
    assert main(["info", "--port", url, "--json", "--timeout", str(TIMEOUT_S)]) == 0
    return json.loads(capsys.readouterr().out)


def test_configuration_survives_a_reset_through_eeprom(
        sim_url: Callable[..., str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    url = sim_url(eeprom=tmp_path / "eeprom.bin")
    with board(url) as (link, hello):
        assert hello.sample_rate_hz == factory_rate(url)
        link.command(msgs.SetRate(rate_hz=200))
        link.command(msgs.SetFilter(kind=msgs.FilterKind.ANALYTICAL, accel_sigma=0, p0=0,
                                    flags=0))
        link.command(msgs.SaveEeprom(confirm=0x5AFE), timeout_s=TIMEOUT_S)
        link.command(msgs.SetRate(rate_hz=100))  # not saved: a reset forgets it
        hello = hello_after_reset(link)
        assert hello.sample_rate_hz == 200 and hello.eeprom == msgs.EepromState.OK
        frames = stream(link, 60)
    # The saved rate and filter are what runs: frames on a 5 ms grid (a real loop start has
    # some µs of jitter; a loop overrun, counted in status, skips a period: APP.md "Timing"),
    # and the analytical estimate (eq. 12) has no rates (ω = 0), while it runs.
    dt = [b[0] - a[0] for a, b in pairwise(frames[10:])]
    periods = [round(d / 5000) for d in dt]
    assert all(k >= 1 and abs(d - 5000 * k) <= 200 for d, k in zip(dt, periods, strict=True)), dt
    assert periods.count(1) >= 0.9 * len(periods), dt
    assert all(m.health & msgs.FilterHealth.RUNNING for _, m in frames[10:])
    assert all(m.omega_a == 0 == m.omega_b for _, m in frames[10:])
    # A new start of the board (power cycle) reads the same EEPROM file.
    doc = info_json(capsys, url)
    assert doc["sample_rate_hz"] == 200 and doc["eeprom"] == "ok" and doc["eeprom_warning"] is None


def test_a_corrupted_eeprom_falls_back_to_defaults_and_the_host_says_so(
        sim_url: Callable[..., str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    image = tmp_path / "eeprom.bin"
    url = sim_url(eeprom=image)
    with board(url) as (link, _):
        link.command(msgs.SetRate(rate_hz=200))
        link.command(msgs.SaveEeprom(confirm=0x5AFE), timeout_s=TIMEOUT_S)
    assert info_json(capsys, url)["sample_rate_hz"] == 200
    raw = bytearray(image.read_bytes())
    raw[6] ^= 0x01  # the first payload byte (the rate's low byte): the CRC no longer matches
    image.write_bytes(bytes(raw))
    doc = info_json(capsys, url)
    assert doc["eeprom"] == "bad_checksum_defaults"
    assert doc["sample_rate_hz"] == factory_rate(url)  # factory default, not the 200 Hz saved
    assert "failed its checksum" in doc["eeprom_warning"]
    assert main(["info", "--port", url, "--timeout", str(TIMEOUT_S)]) == 0
    out = capsys.readouterr().out
    assert "EEPROM bad_checksum_defaults" in out and "warning: the EEPROM image failed its " \
        "checksum: the board runs on factory defaults" in out, out
    # record says so too (it used to say nothing), on stderr, and in its JSON.
    rec = tmp_path / "bad.jrec"
    assert main(["record", "--port", url, "--seconds", "0.3", "--out", str(rec), "--json",
                 "--timeout", str(TIMEOUT_S)]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["eeprom"] == "bad_checksum_defaults"
    assert "jointangle record: warning: the EEPROM image failed its checksum" in cap.err
    # Saving again repairs it.
    with board(url) as (link, hello):
        assert hello.eeprom == msgs.EepromState.BAD_CHECKSUM_DEFAULTS
        link.command(msgs.SaveEeprom(confirm=0x5AFE), timeout_s=TIMEOUT_S)
        assert hello_after_reset(link).eeprom == msgs.EepromState.OK


def test_a_file_that_is_not_an_eeprom_image_is_refused_and_left_as_it_is(
        sim_url: Callable[..., str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    # eeprom= naming someone's file by mistake: the board does not pad it to 4 KB, it refuses.
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    capsys.readouterr()
    assert main(["info", "--port", sim_url(eeprom=notes), "--timeout", "5"]) == 2
    err = capsys.readouterr().err
    assert "notes.txt is not an EEPROM image of this board (9 bytes" in err, err
    assert notes.read_text() == "my notes\n"
