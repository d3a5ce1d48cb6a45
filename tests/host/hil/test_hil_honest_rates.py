"""HIL on the real Mega image (`sim://avr`, whatever $JOINTANGLE_HIL_TARGETS says): the board
measures the rate it holds at >= 20 % asleep (status `sustainable_rate_hz`) and refuses a
set_rate above it, naming that rate; forced, it takes it (issue 17, item 2). On the Pico
(`sim://pico`) the bus is the bound: a loop's SCL periods within 96 % of the period (APP.md
"Commands"), and with two ADXL345 a channel it holds 1000 Hz (issue 19)."""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path
from urllib.parse import urlencode

import pytest

from jointangle.bench.firmware import bench_rig
from jointangle.boards.options import LaunchOptions
from jointangle.cli.main import main
from jointangle.io.rig_file import write_rig
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.link import CommandError, Link
from jointangle.transport import open_port


def sustainable(link: Link, timeout_s: float = 60.0) -> int:
    """The board's sustainable_rate_hz once it has measured a second of loops."""
    link.command(msgs.StartStream(mode=msgs.StreamMode.STATUS | msgs.StreamMode.SAMPLE_ESTIMATE,
                                  status_interval_ms=200))
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            for fr in link.poll():
                if fr.msg_id == msgs.Status.MSG_ID:
                    st = decode_message(fr)
                    assert isinstance(st, msgs.Status)
                    if st.sustainable_rate_hz:
                        return int(st.sustainable_rate_hz)
        raise AssertionError("no status with a sustainable rate")
    finally:
        link.command(msgs.StopStream())


def test_the_mega_refuses_a_rate_it_cannot_hold_and_names_the_one_it_can() -> None:
    with open_port("sim://avr", launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        hello = link.handshake()
        assert hello.sample_rate_hz == 250  # the Mega's factory rate
        held = sustainable(link)
        # Four ADXL345, the EKF, the full stream: `bench firmware`'s cycle-exact loop holds 290 Hz
        # at 20.5 % asleep and 300 Hz at 17.8 %: the board's figure must not promise more.
        assert 250 <= held <= 290 and held % 10 == 0, held
        with pytest.raises(CommandError, match=f"at most {held} Hz") as err:
            link.command(msgs.SetRate(rate_hz=500))
        assert err.value.code == msgs.ErrorCode.RATE_NOT_SUSTAINABLE
        assert err.value.detail == held
        assert link.handshake().sample_rate_hz == 250  # unchanged
        link.command(msgs.SetRate(rate_hz=held))
        assert link.handshake().sample_rate_hz == held
        link.command(msgs.SetRate(rate_hz=500, force=1))  # the user's call: taken
        assert link.handshake().sample_rate_hz == 500


def test_the_pico_names_the_rate_its_bus_holds(capsys: pytest.CaptureFixture[str]) -> None:
    """Four ADXL345 a channel each take 435 SCL periods a loop, 1.089 ms at I2C0's 2504 ns: the
    board says 880 Hz (its CPU would hold 1000) and refuses more, naming it."""
    assert main(["info", "--port", "sim://pico", "--rates", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sample_rate_hz"] == 800  # the Pico's factory rate
    assert doc["achieved_rate_hz"] == pytest.approx(800, rel=0.01)
    assert doc["sustainable_rate_hz"] == 880
    with open_port("sim://pico", launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        link.handshake()
        for rate in (890, 1000):  # refused before the board has measured anything, too
            with pytest.raises(CommandError, match="at most 880 Hz") as err:
                link.command(msgs.SetRate(rate_hz=rate))
            assert err.value.code == msgs.ErrorCode.RATE_NOT_SUSTAINABLE
            assert err.value.detail == 880
        assert sustainable(link) == 880
        link.command(msgs.SetRate(rate_hz=880))
        assert link.handshake().sample_rate_hz == 880
        link.command(msgs.SetRate(rate_hz=1000, force=1))  # the user's call: taken
        assert link.handshake().sample_rate_hz == 1000


def test_the_pico_holds_1000_hz_with_two_adxl345_a_channel(tmp_path: Path) -> None:
    """Issue 19, acceptance: four ADXL345 through the multiplexer at 400 kHz, two a channel
    (0x53, 0x1D), hold 1000 Hz — the board takes set_rate 1000 without force, its own 1 s window
    counts 1000 loops, and every frame carries four fresh samples (ADXL345 ODR 1600 Hz), with the
    full stream at 1 Mbaud and nothing lost."""
    rig = tmp_path / "paired.toml"
    write_rig(bench_rig("adxl345", 1000, channel_per_link=True), rig)
    url = f"sim://pico?{urlencode({'rig': rig, 'fast': 1}, safe='/')}"
    with open_port(url, launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        link.handshake()
        link.command(msgs.SetRate(rate_hz=1000))  # no force: the board says it holds it
        assert link.handshake().sample_rate_hz == 1000
        link.command(msgs.StartStream(
            mode=msgs.StreamMode.STATUS | msgs.StreamMode.SAMPLE_ESTIMATE, status_interval_ms=250))
        t_us, first = status_after(link, 0)  # the counts from here on are the stream's
        seqs: list[int] = []
        stale = 0
        deadline = t_us + WINDOW_WAIT_US
        st: msgs.Status | None = None
        while st is None:
            for fr in link.poll():
                if fr.t_us <= t_us + 500_000:
                    continue
                seqs.append(fr.seq)  # (every frame takes a seq)
                if fr.msg_id == msgs.SampleEstimate.MSG_ID:
                    m = decode_message(fr)
                    assert isinstance(m, msgs.SampleEstimate)
                    stale += sum(1 for s in m.sensors if not s.fresh)
                elif fr.msg_id == msgs.Status.MSG_ID and fr.t_us >= deadline:
                    st = decode_message(fr)
                    assert isinstance(st, msgs.Status)
    assert st.loop_rate_hz == pytest.approx(1000, rel=HOLD_TOLERANCE), st
    assert st.sustainable_rate_hz == 1000, st
    assert (st.loop_overruns, st.uart_drops) == (first.loop_overruns, first.uart_drops), st
    assert len(seqs) > 2000 and stale == 0, (len(seqs), stale)
    assert all((b - a) % 65536 == 1 for a, b in itertools.pairwise(seqs)), "a frame was lost"


def test_info_rates_shows_configured_achieved_and_sustainable_side_by_side(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "--port", "sim://native", "--rates", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sample_rate_hz"] == 500  # the native board's factory rate
    assert doc["achieved_rate_hz"] == pytest.approx(500, rel=0.02)
    assert doc["sustainable_rate_hz"] >= 500 and doc["sustainable_rate_hz"] % 10 == 0
    assert main(["info", "--port", "sim://native", "--rates"]) == 0
    assert "rates: configured 500 Hz, achieved" in capsys.readouterr().out


# Issue 17, acceptance: asked for any rate from 50 to 1000 Hz, a board either holds it (its own
# 1 s loop-rate window within 1 % of the rate) or refuses it naming its sustainable rate — never
# runs below that rate because of overruns. The Mega image, the Pico image and the native board,
# with four ADXL345 and with four BNO055 (on the Pico the bus refuses 1000 Hz naming 880).
SWEEP_HZ = (50, 100, 200, 300, 500, 1000)
HOLD_TOLERANCE = 0.01
# A status this long after the first one after set_rate reports a whole 1 s window at the new
# rate (set_rate probes every sensor first: ~0.8 s of device time with BNO055s).
WINDOW_WAIT_US = 3_200_000


def status_after(link: Link, device_us: int,
                 timeout_s: float = 120.0) -> tuple[int, msgs.Status]:
    """The first status stamped at least `device_us` (device time) and its stamp, reading
    everything else."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for fr in link.poll():
            if fr.msg_id == msgs.Status.MSG_ID and fr.t_us >= device_us:
                st = decode_message(fr)
                assert isinstance(st, msgs.Status)
                return fr.t_us, st
    raise AssertionError(f"no status after device time {device_us} us")


@pytest.mark.parametrize("model", ["adxl345", "bno055"])
@pytest.mark.parametrize("board", ["sim://avr", "sim://native", "sim://pico"])
def test_every_rate_is_held_or_refused_naming_the_sustainable_one(
        board: str, model: str, tmp_path: Path) -> None:
    rig = tmp_path / f"{model}.toml"
    write_rig(bench_rig(model, 200), rig)
    url = f"{board}?{urlencode({'rig': rig, 'fast': 1}, safe='/')}"
    held: list[int] = []
    full = msgs.StartStream(mode=msgs.StreamMode.STATUS | msgs.StreamMode.SAMPLE_ESTIMATE,
                            status_interval_ms=250)
    with open_port(url, launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        link.handshake()

        def ask(rate: int) -> bool:
            """set_rate (between streams: the board takes it only then); True when taken."""
            link.command(msgs.StopStream())
            try:
                link.command(msgs.SetRate(rate_hz=rate))
                return True
            finally:
                link.command(full)

        def holds(rate: int) -> None:
            # A status from a whole 1 s window after the new rate took effect (the first one
            # read may still be from the stream before it).
            t_us, _ = status_after(link, 0)
            _, st = status_after(link, t_us + WINDOW_WAIT_US)
            assert st.loop_rate_hz == pytest.approx(rate, rel=HOLD_TOLERANCE), (rate, st)

        link.command(full)
        for rate in SWEEP_HZ:
            try:
                ask(rate)
            except CommandError as err:
                assert err.code == msgs.ErrorCode.RATE_NOT_SUSTAINABLE, err
                assert 0 < err.detail < rate, (rate, err.detail)
                # The rate it names, it holds (and takes without force).
                assert ask(err.detail)
                holds(err.detail)
                continue
            holds(rate)
            held.append(rate)
    print(f"{board} with four {model}: held {held} Hz, refused the rest")
    assert held[:3] == [50, 100, 200], held  # every board holds these with either set


@pytest.mark.parametrize("model", ["adxl345", "adxl357", "bno055"])
@pytest.mark.parametrize("board", ["sim://avr", "sim://native"])
def test_the_factory_rate_is_held_at_20_percent_asleep_with_every_sensor_set(
        board: str, model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 17, acceptance: a fresh EEPROM boots at a rate the board holds with >= 20 % asleep
    whichever parts are fitted — its factory rate (`info` of a fresh board), with four of each
    model at it and the full stream, is at most the board's own sustainable rate."""
    capsys.readouterr()
    assert main(["info", "--port", board, "--json"]) == 0
    factory = json.loads(capsys.readouterr().out)["sample_rate_hz"]
    rig = tmp_path / f"{model}.toml"
    write_rig(bench_rig(model, factory), rig)
    url = f"{board}?{urlencode({'rig': rig, 'fast': 1}, safe='/')}"
    capsys.readouterr()
    assert main(["info", "--port", url, "--rates", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    print(f"\n{board} with four {model}: configured {doc['sample_rate_hz']} Hz, achieved "
          f"{doc['achieved_rate_hz']} Hz, sustainable {doc['sustainable_rate_hz']} Hz")
    assert doc["sample_rate_hz"] == factory
    assert doc["achieved_rate_hz"] == pytest.approx(factory, rel=HOLD_TOLERANCE), doc
    assert doc["sustainable_rate_hz"] >= factory, doc
