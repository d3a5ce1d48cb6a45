"""ctest firmware.avr_image_stream: the real Mega 2560 image (jointangle_mega2560.elf) in the AVR
virtual board (ja_avr_board, simavr 1.6) with four ADXL345 behind the TCA9548A.

Checks: the boot hello (board mega2560, four ADXL345 whose DEVID 0xE5 was read through the
multiplexer, no fault bits); start_stream is acked; then SECONDS of sample_estimate frames with
consecutive seq, t_us one period apart (+- wake-up jitter), every sensor fresh and fault-free,
the filter running; status frames without UART drops; a reset command is acked and the
watchdog restarts the chip (a new hello, one reset in the report); static RAM + stack peak <= 6 KB
(from the board's --report). Prints the loop accounting (loop rate, sleep fraction, cycles per
activity, bus occupancy at 400 kHz) so the ctest log carries the measured figures.
Messages, layouts and framing are the host's generated protocol module (through
board_test_lib.py beside this file, with the board process).

With `nack` as the fourth argument the board runs in real time with a NACK fault on sensor a.1
from 1.5 to 1.8 simulated seconds: that sensor's samples carry the nack bit for a while, the
others stay fresh and fault-free, no frame is lost, and at the end all four are fine again
(re-probed) and the filter runs.

With `overload` (and JA_AVR_TEST_RATE=500, more than the Mega's loop holds: ~1.5 periods a
loop, `jointangle bench firmware`) the frames must come a whole number of periods apart, never
more than two, and more than 0.6 x RATE a second: a loop that overruns is followed at once by the
next, stamped with the last slot at or before its start. A longer gap is a late
wake-up (simavr 1.6 sleeps on `sleep` whatever SMCR.SE says; firmware/platform/avr/board/clock.hpp).

usage: test_mega2560_image.py PATH/TO/ja_avr_board PATH/TO/jointangle_mega2560.elf
       [SECONDS [nack|overload]]
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import tempfile
from pathlib import Path

from board_test_lib import (
    BoardProcess,
    Frame,
    FrameReader,
    command,
    decode_message,
    four_adxl345_rig,
    kill_started,
    msgs,
    write_swing_motion,
)

RATE = int(os.environ.get("JA_AVR_TEST_RATE", "500"))
RIG = four_adxl345_rig("ctest-mega2560", RATE)

HELLO, SAMPLE_ESTIMATE, STATUS = msgs.Hello.MSG_ID, msgs.SampleEstimate.MSG_ID, msgs.Status.MSG_ID
ACK, CALIBRATION = msgs.Ack.MSG_ID, msgs.Calibration.MSG_ID
ADXL345_DEVID = 0xE5  # the part's DEVID register (firmware/drivers)
FAULT_BITS = (msgs.SensorStatus.NACK | msgs.SensorStatus.WRONG_ID | msgs.SensorStatus.SATURATED
              | msgs.SensorStatus.FROZEN | msgs.SensorStatus.NOT_CONFIGURED)
SAVE_CONFIRM = 0x5AFE  # save_eeprom's guard value (protocol/messages.toml)
SRAM_BUDGET = 6 * 1024
JITTER_US = 100


def acked(frames: list[Frame], cmd: type[msgs.Message], seq: int) -> bool:
    """Whether an ack with error ok answers command `cmd` sent with `seq`."""
    return any(isinstance(a, msgs.Ack) and (a.command_id, a.command_seq, a.error)
               == (cmd.MSG_ID, seq, msgs.ErrorCode.OK)
               for a in (decode_message(f) for f in frames if f.msg_id == ACK))


def check(cond: bool, what: str, failures: list[str]) -> None:
    if not cond:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def main() -> int:
    board, elf = sys.argv[1], sys.argv[2]
    seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 2.0
    fault = len(sys.argv) > 4 and sys.argv[4] == "nack"
    overload = len(sys.argv) > 4 and sys.argv[4] == "overload"
    timing = ["--fault", "a.1:nack@1.5-1.8"] if fault else ["--fast", "--measure-from", "1.0"]
    failures: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "rig.toml").write_text(RIG)
        write_swing_motion(work / "motion.csv", 4 * seconds + 10, 1000.0)
        report = work / "report.json"
        b = BoardProcess([board, "--rig", str(work / "rig.toml"), "--motion",
                          str(work / "motion.csv"), *timing, "--report", str(report), elf])
        try:
            fd = b.fd
            rd = FrameReader(fd)
            boot = rd.read(lambda g: any(f.msg_id == HELLO for f in g), 30)
            hellos = [decode_message(f) for f in boot if f.msg_id == HELLO]
            check(bool(hellos), "a hello at boot", failures)
            if hellos:
                h = hellos[0]
                assert isinstance(h, msgs.Hello)
                check(h.board == msgs.Board.MEGA2560, f"hello board {h.board} is mega2560",
                      failures)
                check(h.sample_rate_hz == RATE, f"hello rate {RATE} Hz", failures)
                n = len(h.sensors)
                check(n == 4, f"hello lists 4 sensors (got {n})", failures)
                for i, s in enumerate(h.sensors):
                    check(s.model == msgs.SensorModel.ADXL345 and s.chip_id == ADXL345_DEVID
                          and s.mux_channel == i and s.address == 0x53 and s.status == 0,
                          f"hello sensor {i}: model {s.model} chip 0x{s.chip_id:02x} mux "
                          f"{s.mux_channel} addr 0x{s.address:02x} status 0x{s.status:02x}",
                          failures)
            if not fault and not overload:  # (the fault run is in real time: keep it short)
                # The deepest stacks: set_joint (filter reconfigured), save_eeprom (the image built
                # and written, ~1.9 s of EEPROM writes with the watchdog kicked per byte) and
                # get_calibration from the EEPROM (CRC over the image).
                os.write(fd, command(msgs.SetJoint(link=msgs.Link.A, x=300000, y=0), 4))
                os.write(fd, command(msgs.SaveEeprom(confirm=SAVE_CONFIRM), 5))
                os.write(fd, command(msgs.GetCalibration(
                    slot=0, source=msgs.CalibrationSource.EEPROM), 6))
                got = rd.read(lambda g: acked(g, msgs.GetCalibration, 6), 120)
                for cmd, seq in ((msgs.SetJoint, 4), (msgs.SaveEeprom, 5),
                                 (msgs.GetCalibration, 6)):
                    check(acked(got, cmd, seq), f"command {cmd.__name__} acked ok", failures)
                check(any(f.msg_id == CALIBRATION for f in got), "calibration read back",
                      failures)
            # A reset command: acked, the watchdog restarts the chip, a new hello (before the
            # stream, so the report's window after --measure-from holds only streaming).
            os.write(fd, command(msgs.Reset(kind=msgs.ResetKind.REBOOT), 3))
            after = rd.read(lambda g: any(f.msg_id == HELLO for f in g), 60)
            check(acked(after, msgs.Reset, 3), "reset acked ok", failures)
            check(any(f.msg_id == HELLO and f.seq == 0 for f in after),
                  "a new hello (seq 0) after the reset", failures)
            # Stream sample_estimate + status every 500 ms; skip the first 100 frames.
            mode = msgs.StreamMode.SAMPLE_ESTIMATE | msgs.StreamMode.STATUS
            os.write(fd, command(msgs.StartStream(mode=mode, status_interval_ms=500, every=1), 1))
            want = int(seconds * RATE)
            frames = rd.read(lambda g: sum(f.msg_id == SAMPLE_ESTIMATE for f in g) >= want + 100,
                             600)
            check(acked(frames, msgs.StartStream, 1), "start_stream acked ok", failures)
            se = [f for f in frames if f.msg_id == SAMPLE_ESTIMATE][100:]
            check(len(se) >= want, f"{want} sample_estimate frames (got {len(se)})", failures)
            check(rd.bad == 0, f"no broken frames (got {rd.bad})", failures)
            seq_gaps = t_gaps = stale = faulty = not_running = 0
            for prev, cur in itertools.pairwise(se):
                seq_gaps += (cur.seq - prev.seq) & 0xFFFF != 1 + sum(
                    1 for f in frames if f.msg_id != SAMPLE_ESTIMATE and prev.seq < f.seq < cur.seq)
                dt = (cur.t_us - prev.t_us) & 0xFFFFFFFF
                # t_us is the loop's grid slot: one period apart (overload: one or two).
                periods = round(dt * RATE / 1e6)
                allowed = (1, 2) if overload else (1,)
                if periods not in allowed or abs(dt - periods * 1000000 // RATE) > JITTER_US:
                    t_gaps += 1
                    if t_gaps <= 5:
                        print(f"t_us gap: seq {prev.seq} -> {cur.seq}: {dt} us", file=sys.stderr)
            nacked = 0
            for k, f in enumerate(se):
                m = decode_message(f)
                assert isinstance(m, msgs.SampleEstimate)
                # With the fault: sensor 1 may be out (its link's filter with it) until it is
                # re-probed; the last 50 frames must be clean again.
                excused = fault and k < len(se) - 50
                not_running += not m.health & msgs.FilterHealth.RUNNING and not excused
                for i, s in enumerate(m.sensors):
                    if excused and i == 1:
                        nacked += (s.status & msgs.SensorStatus.NACK) != 0
                        continue
                    stale += s.fresh != 1
                    faulty += (s.status & FAULT_BITS) != 0
                    if s.status & FAULT_BITS and faulty < 5:
                        print(f"seq {f.seq} sensor {i} status 0x{s.status:02x}", file=sys.stderr)
            if fault:
                check(nacked >= 10, f"sensor a.1 flagged nack during the fault ({nacked} frames)",
                      failures)
            apart = "one or two periods" if overload else "one period"
            check(t_gaps == 0, f"frames {apart} (+-{JITTER_US} us) apart (gaps: {t_gaps})",
                  failures)
            if overload and len(se) > 1:
                # A late loop's successor starts at once (APP.md "Timing"): the loop runs as
                # fast as its work allows (~340 a second), not at every other slot (250).
                span_s = ((se[-1].t_us - se[0].t_us) & 0xFFFFFFFF) / 1e6
                loops_per_s = (len(se) - 1) / span_s
                print(f"overloaded: {loops_per_s:.1f} loops a second at {RATE} Hz asked",
                      file=sys.stderr)
                check(loops_per_s > 0.6 * RATE, f"more than {0.6 * RATE:g} loops a second "
                      f"(got {loops_per_s:.1f})", failures)
            check(seq_gaps == 0, f"no frame lost (seq gaps: {seq_gaps})", failures)
            check(stale == 0, f"every sample fresh (stale: {stale})", failures)
            check(faulty == 0, f"no sensor fault (faulty samples: {faulty})", failures)
            check(not_running == 0, f"filter running (frames without: {not_running})", failures)
            for f in frames:
                if f.msg_id == STATUS:
                    st = decode_message(f)
                    assert isinstance(st, msgs.Status)
                    print(f"status: uptime {st.uptime_ms} ms, overruns {st.loop_overruns}, uart "
                          f"drops {st.uart_drops}, loop rate {st.loop_rate_hz} Hz, idle "
                          f"{st.idle_permille / 10:.1f} %")
                    check(st.uart_drops == 0, f"no UART drops (status says {st.uart_drops})",
                          failures)
            rc = b.stop(30)[0]
        finally:
            kill_started()
        check(rc == 0, f"board exit status {rc}", failures)
        if report.exists():
            r = json.loads(report.read_text())
            ram = r["static_ram_bytes"] + r["stack_peak_bytes"]
            print(f"flash {r['flash_bytes']} B, static RAM {r['static_ram_bytes']} B, "
                  f"stack peak {r['stack_peak_bytes']} B")
            print(f"loop rate {r['loop_rate_hz']:.1f} Hz, asleep {100 * r['idle_fraction']:.1f} %"
                  f", bus occupancy at 400 kHz {100 * r['bus']['occupancy']:.1f} %")
            # Loops from the frames' time stamps (the report's own count also counts an ISR
            # restoring id 3 as an entry into the filter).
            span_s = ((se[-1].t_us - se[0].t_us) & 0xFFFFFFFF) / 1e6 if len(se) > 1 else 0.0
            loops_per_s = (len(se) - 1) / span_s if span_s > 0 else 0.0
            print(f"loops per second from the frames: {loops_per_s:.1f}")
            for k, a in sorted(r["activity"].items(), key=lambda kv: int(kv[0])):
                per_loop = a["cycles"] / r["seconds"] / loops_per_s if loops_per_s else 0.0
                print(f"  activity {k} {a['name']}: {per_loop:.0f} cycles per loop")
            if loops_per_s:
                print(f"  asleep: {r['sleep_cycles'] / r['seconds'] / loops_per_s:.0f} cycles"
                      " per loop")
            check(ram <= SRAM_BUDGET, f"static RAM + stack {ram} B <= {SRAM_BUDGET}", failures)
            check(r["resets"] == 1, f"one (watchdog) reset (got {r['resets']})", failures)
            if overload:
                check(loops_per_s < 0.9 * RATE, f"the loop overran at {RATE} Hz "
                      f"({loops_per_s:.0f} loops a second): the test proves nothing", failures)
        else:
            check(False, "the board wrote its --report", failures)
    print("ok" if not failures else f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
