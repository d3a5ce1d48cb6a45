"""`jointangle calibrate [--port URL]`: the guided flow against a board (or the virtual board).

Asks for the paper's seven holds in order (--method gravity, fixture-free: flat, link up, then
ten new orientations of any kind), shows a live "hold still" indicator and progress,
checks each hold as it is taken (still, along the asked axis; otherwise rejected with the reason
and asked again), fits every sensor (Appendix IV), and only when every sensor passes: writes
S and offset to the board (set_calibration), stores them (save_eeprom), reads them back from the
board's EEPROM and compares, then writes the calibrated rig to a NEW file (or --out; when --out is
the rig file itself the original is kept next to it first).

With --motion-seconds S the flow goes on to the geometry: the user moves the joint freely for S
seconds, the lever arms, mountings and joints are fitted from that motion (calibration/motion.py)
on the rig just calibrated, the joint's zero taken from the straight holds (±x, ±y: the rig
straight, θ = 0; calibration/reference.py), and the geometry is written to the board (every
set_sensor and set_joint, the calibrations again, save_eeprom, calibrations read back from
EEPROM, the inventory checked) and to the rig file. A motion that is refused writes nothing of
the geometry (exit 1; the board and the rig file keep the sensor calibration).

With a virtual board (sim://native, the default when no board is attached) the board plays the
same poses in the same order (`sim.static_poses.guided_motion_poses`), optionally with unknown
sensor errors (--inject-errors) and one mistaken hold (--sim-mistake) that the flow must reject;
with --motion-seconds, then `gravity-free-motion`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.live import Live
from rich.text import Text

from jointangle.boards.options import SIM_PREFIX, LaunchOptions
from jointangle.calibration.board import (
    ReadbackError,
    SlotWrite,
    StreamReadings,
    read_calibration,
    write_calibration,
)
from jointangle.calibration.guided import FlowState, GuidedSettings, PoseAttempt, PoseCollector
from jointangle.calibration.motion import MotionPrior, calibrate_motion, motion_calibrated_rig
from jointangle.calibration.pipeline import calibrated_rig
from jointangle.calibration.reference import (
    combine_references,
    measure_reference,
    referenced_rig,
)
from jointangle.cli.common import nonnegative_float, positive_float, positive_int
from jointangle.cli.live import cbreak, read_key
from jointangle.cli.motion_report import motion_doc, reference_doc
from jointangle.device.configure import (
    CALIBRATION_FIELDS,
    SAVE_CONFIRM,
    SAVE_TIMEOUT_S,
    rig_commands,
)
from jointangle.device.rig import check_inventory, device_rig
from jointangle.errors import InputError
from jointangle.io.csv_formats import AccelData, write_accel_csv
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.live.stream import DeviceStream
from jointangle.protocol import messages as msgs
from jointangle.protocol.link import CommandError, LinkTimeoutError
from jointangle.rig import Rig
from jointangle.sim.scenarios import gravity_rig, simulate
from jointangle.sim.static_poses import (
    guided_motion_poses,
    guided_sequence,
    static_pose_recording,
    with_sensor_errors,
)
from jointangle.transport import resolve_url

SIM_RATE_HZ = 500.0
SIM_PREROLL_S = 3.0  # handling before the first hold while the host connects
SIM_MOTION_MARGIN_S = 30.0  # sim boards: free motion beyond --motion-seconds


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("guided flow against a board (no --poses)")
    g.add_argument("--port", metavar="URL", default=None,
                   help="serial port or virtual board (sim://native); default: the first "
                   "Arduino Mega or USB-serial bridge found, else sim://native")
    g.add_argument("--baud", type=positive_int, default=500_000,
                   help="baud rate (default %(default)s)")
    g.add_argument("--timeout", type=positive_float, default=1.0, metavar="S",
                   help="seconds to wait for each answer (default %(default)s)")
    g.add_argument("--hold", type=positive_float, default=2.0, metavar="S",
                   help="seconds to hold each pose still (default %(default)s)")
    g.add_argument("--pose-timeout", type=positive_float, default=300.0, metavar="S",
                   help="give up when a pose is not taken within this long (default "
                   "%(default)s)")
    g.add_argument("--motion-seconds", type=nonnegative_float, default=0.0, metavar="S",
                   help="after the poses, the geometry step: move the joint freely for S "
                   "seconds (30-60), and each sensor's lever arm and mounting and each joint "
                   "are fitted from the motion (--method motion), the joint's zero taken "
                   "from the poses' straight holds; the fitted geometry is written to the "
                   "board (set_sensor, set_joint) and the rig file (default 0: no motion "
                   "step). Tolerances: --position-tolerance-mm, --joint-tolerance-mm, "
                   "--mounting-tolerance-deg")
    g.add_argument("--yes", action="store_true",
                   help="write without asking (otherwise: confirm with y + Enter)")
    g.add_argument("--sim-mistake", type=positive_int, metavar="K", default=None,
                   help="sim:// boards: hold a wrong pose where pose K is expected (--method "
                   "gravity: K ≥ 2 repeats the pose before)")
    g.add_argument("--sim-preroll", type=nonnegative_float, default=SIM_PREROLL_S, metavar="S",
                   help="sim:// boards: seconds of handling before the first pose (covers "
                   "the time the host takes to connect; default %(default)s)")
    g.add_argument("--sim-hold", type=positive_float, default=4.0, metavar="S",
                   help="sim:// boards: seconds the simulated rig holds each pose (the board "
                   "plays the flow's poses in order; add ?fast=1 to the URL to run it faster "
                   "than real time)")


def _output_path(rig_path: Path | None, out: str | None) -> tuple[Path, Path | None]:
    """Where the calibrated rig goes, and where the original is kept when --out is the rig."""

    def fresh(base: Path, suffix: str) -> Path:
        cand = base.with_name(base.stem + suffix + ".toml")
        k = 2
        while cand.exists():
            cand = base.with_name(f"{base.stem}{suffix}-{k}.toml")
            k += 1
        return cand

    if out:
        target = Path(out)
        if rig_path is not None and target.exists() and target.resolve() == rig_path.resolve():
            return target, fresh(rig_path, ".orig")
        return target, None
    if rig_path is not None:
        return fresh(rig_path, ".calibrated"), None
    return fresh(Path.cwd() / "rig", ".calibrated"), None


def _sim_board(args: argparse.Namespace, rig: Rig, workdir: Path) -> tuple[Rig, LaunchOptions]:
    """The virtual board's rig (with --inject-errors) and the static poses it plays."""
    board_rig = rig.with_sample_rate(SIM_RATE_HZ)
    if args.inject_errors is not None:
        board_rig = with_sensor_errors(board_rig, args.inject_errors)
    labels = guided_sequence(args.method)
    mistake = None
    if args.sim_mistake is not None:
        if not 1 <= args.sim_mistake <= len(labels):
            raise InputError(f"must be 1-{len(labels)}", field="--sim-mistake")
        mistake = args.sim_mistake - 1
    if not args.sim_hold > args.hold + 0.5:
        raise InputError(f"must exceed --hold ({args.hold:g} s) by more than 0.5 s",
                         field="--sim-hold")
    rec = static_pose_recording(board_rig, guided_motion_poses(labels, mistake, args.seed),
                                seed=args.seed,
                                hold_s=args.sim_hold, move_s=1.0,
                                preroll_s=args.sim_preroll)
    t, readings = rec.t, rec.readings
    if args.motion_seconds > 0:
        # then the joint swung freely (a margin beyond --motion-seconds for the fits between)
        free = simulate("gravity-free-motion", seed=args.seed, rate_hz=SIM_RATE_HZ,
                        seconds=args.motion_seconds + SIM_MOTION_MARGIN_S, rig=board_rig)
        t = np.concatenate([t, t[-1] + 1.0 / SIM_RATE_HZ + free.t])
        readings = np.concatenate([readings, free.readings], axis=0)
    rig_path, motion = workdir / "rig.toml", workdir / "poses.csv"
    write_rig(board_rig, rig_path)
    write_accel_csv(motion, board_rig, AccelData(t=t, readings=readings))
    opts = LaunchOptions(rig_path=rig_path, motion_path=motion, loop=False, seed=args.seed,
                         baud=args.baud)
    return board_rig, opts


def _bar(frac: float, width: int = 24) -> str:
    n = round(max(0.0, min(1.0, frac)) * width)
    return "█" * n + "░" * (width - n)


def render(st: FlowState) -> Text:
    t = Text()
    t.append(f"calibration: pose {min(st.index + 1, st.total)} of {st.total}  "
             f"{_bar(st.index / max(st.total, 1), 14)}\n", style="bold")
    if st.phase == "done":
        t.append("all poses taken\n", style="green")
    else:
        t.append(f"next: {st.label} — {st.instruction}\n")
        if st.phase == "move":
            t.append("  move the rig to this pose…\n", style="yellow")
        else:
            t.append(f"  HOLD STILL {_bar(st.still_s / st.hold_s)} "
                     f"{min(st.still_s, st.hold_s):.1f}/{st.hold_s:.1f} s\n",
                     style="green" if st.still_s > 0 else "yellow")
    if st.message:
        t.append(f"  {st.message}\n", style="red" if "rejected" in st.message else "")
    t.append("  q: stop (nothing is written)\n", style="dim")
    return t


def _attempt_doc(a: PoseAttempt) -> dict[str, Any]:
    return {"pose": a.label, "t_start": a.t_start, "t_stop": a.t_stop, "accepted": a.accepted,
            "reason": a.reason, "axes": a.axes}


def collect(stream: DeviceStream, collector: PoseCollector, conv: StreamReadings,
            pose_timeout_s: float, interactive: bool, console: Console, log: Any) -> None:
    """Feed the stream to the collector until every pose is taken (the UI loop)."""
    live_ctx: Any = (Live(render(collector.state), console=console, auto_refresh=False)
                     if interactive else contextlib.nullcontext())
    keys_ctx: Any = cbreak(sys.stdin) if interactive else contextlib.nullcontext()
    started = time.monotonic()
    last_index = -1
    next_line = 0.0
    with live_ctx as live, keys_ctx:
        while not collector.done:
            if interactive and read_key(sys.stdin) in ("q", "Q"):
                raise InputError("stopped by the user (q): nothing written", field="q")
            now = time.monotonic()
            st = collector.state
            if st.index != last_index:
                last_index, started = st.index, now
                if not interactive:
                    log(f"pose {st.index + 1}/{st.total}: {st.label} — {st.instruction}")
            if now - started > pose_timeout_s:
                raise InputError(f"pose {st.label} was not taken within {pose_timeout_s:g} s "
                                 "(hold the rig still in that pose); nothing written",
                                 field="--pose-timeout")
            t, r, faulty = conv.convert(stream.poll())
            for a in collector.feed(t, r, faulty):
                if not interactive:
                    log(f"  pose {a.label} " + ("taken" if a.accepted
                                                 else f"REJECTED: {a.reason}"))
            if interactive:
                live.update(render(collector.state), refresh=True)
            elif now >= next_line and st.phase == "hold" and st.still_s > 0:
                next_line = now + 1.0
                log(f"  holding still {st.still_s:.1f}/{st.hold_s:.1f} s")
            if len(t) == 0:
                time.sleep(0.005)


def _confirm(args: argparse.Namespace, log: Any) -> bool:
    if args.yes:
        return True
    log("write this calibration to the board's EEPROM and the rig file? [y/N] ")
    line = sys.stdin.readline()
    return line.strip().lower() in ("y", "yes")


def run_guided(args: argparse.Namespace,
               print_report: Any, report_doc: Any) -> int:
    url, what = resolve_url(args.port)
    console = Console(stderr=True)
    interactive = sys.stdin.isatty() and sys.stderr.isatty() and not args.json

    def log(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    rig_path = Path(args.rig) if args.rig else None
    workdir = Path(tempfile.mkdtemp(prefix="jointangle-calibrate-"))
    try:
        launch = None
        if url.startswith(SIM_PREFIX):
            user_rig = load_rig(rig_path) if rig_path else gravity_rig(SIM_RATE_HZ)
            # The rig file written at the end is the board's (at its rate, with the injected
            # errors kept as simulation fields); with injected errors it is a new rig, not the
            # user's file.
            file_rig, launch = _sim_board(args, user_rig, workdir)
            if args.inject_errors is not None:
                rig_path = None
        elif rig_path is None:
            raise InputError("a real board needs the rig file of its build (sensor positions "
                             "and mounting)", field="--rig")
        else:
            file_rig = load_rig(rig_path)
        stream = DeviceStream(url, baud=args.baud, launch=launch,
                              handshake_timeout_s=args.timeout)
        hello = stream.connect()
        log(f"{stream.resolved_url}{f' ({what})' if what else ''}: "
            f"{len(hello.sensors)} sensors at {hello.sample_rate_hz} Hz")
        try:
            return _run_connected(args, stream, hello, file_rig, rig_path, interactive,
                                  console, log, print_report, report_doc)
        finally:
            stream.stop()
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _run_connected(args: argparse.Namespace, stream: DeviceStream, hello: msgs.Hello,
                   file_rig: Rig, rig_path: Path | None, interactive: bool, console: Console,
                   log: Any, print_report: Any, report_doc: Any) -> int:
    device_rig(file_rig, hello)  # the rig must describe this board (InputError otherwise)
    rig = file_rig.with_sample_rate(float(hello.sample_rate_hz or file_rig.sample_rate_hz))
    collector = PoseCollector(rig, guided_sequence(args.method), GuidedSettings(hold_s=args.hold))
    conv = StreamReadings(rig)
    stream.start()
    collect(stream, collector, conv, args.pose_timeout, interactive, console, log)
    assert stream.link is not None
    stream.link.command(msgs.StopStream())
    stream.streaming = False
    report = collector.calibrate(args.gravity, args.method, args.align)
    doc: dict[str, Any] = {"port": stream.resolved_url,
                           "attempts": [_attempt_doc(a) for a in collector.state.attempts],
                           "rejected_poses": len(collector.state.rejected),
                           **report_doc(report), "written": False, "readback": None,
                           "rig_out": None, "rig_original_kept": None}

    def finish(code: int) -> int:
        if args.json:
            sys.stdout.write(json.dumps(doc) + "\n")
        return code

    if not args.json:
        print_report(report, Console(stderr=True, width=120))
    if not report.accepted:
        log("calibration rejected: nothing written (" + "; ".join(report.reasons()) + ")")
        return finish(1)
    if not _confirm(args, log):
        log("not confirmed: nothing written")
        return finish(1)
    try:
        writes = write_calibration(stream.link, rig, report)
    except (ReadbackError, CommandError, LinkTimeoutError) as exc:
        # Some slots may hold the new values in RAM now; the EEPROM is not confirmed, and the
        # rig file is left alone.
        log(f"the board did not store the calibration: {exc}")
        doc["written"] = True
        doc["error"] = str(exc)
        return finish(1)
    doc["written"] = True
    doc["readback"] = [_write_doc(w) for w in writes]
    for w in writes:
        log(f"slot {w.slot} ({w.label}): written, saved, read back from EEPROM: identical")
    out_rig = calibrated_rig(file_rig, report, noise=not args.no_noise)
    code = 0
    if args.motion_seconds > 0:
        code, out_rig = _motion_step(args, stream, collector, conv, out_rig, rig.sample_rate_hz,
                                     interactive, log, doc)
    target, keep = _output_path(rig_path, args.out)
    if keep is not None and rig_path is not None:
        shutil.copyfile(rig_path, keep)
        doc["rig_original_kept"] = str(keep)
        log(f"kept the original rig as {keep}")
    write_rig(out_rig, target)
    doc["rig_out"] = str(target)
    log(f"wrote the calibrated rig to {target}")
    return finish(code)


STRAIGHT_POSES = ("+x", "-x", "+y", "-y")
MOTION_LEAD_IN_S = 3.0  # the straight rig (θ = 0), gravity in the plane


def collect_motion(stream: DeviceStream, conv: StreamReadings, seconds: float,
                   timeout_s: float, interactive: bool, log: Any,
                   lead_in_s: float = MOTION_LEAD_IN_S) -> tuple[np.ndarray, np.ndarray]:
    """`seconds` of the stream (t, raw readings) while the user moves the joint, after a
    lead-in that is dropped: getting from the last pose (on the bench, on end) into the swing
    turns the rig out of its plane, which the planar model cannot explain."""
    ts: list[np.ndarray] = []
    rs: list[np.ndarray] = []
    started = time.monotonic()
    next_line = 0.0
    got = -lead_in_s
    t0: float | None = None
    while got < seconds:
        if time.monotonic() - started > timeout_s + seconds:
            raise InputError(f"the board sent {got:.1f} s of samples in {timeout_s + seconds:g} "
                             "s; nothing of the geometry written", field="--motion-seconds")
        t, r, _ = conv.convert(stream.poll())
        if len(t):
            t0 = float(t[0]) if t0 is None else t0
            keep = t >= t0 + lead_in_s  # the lead-in: out of the last pose, into the plane
            ts.append(t[keep])
            rs.append(r[keep])
            got = float(t[-1]) - t0 - lead_in_s
        now = time.monotonic()
        if now >= next_line:
            next_line = now + (0.2 if interactive else 5.0)
            log(f"  get ready: {-got:.0f} s" if got < 0 else
                f"  moving: {min(got, seconds):.0f}/{seconds:g} s")
        if len(t) == 0:
            time.sleep(0.005)
    return np.concatenate(ts), np.concatenate(rs, axis=0)


def _motion_step(args: argparse.Namespace, stream: DeviceStream, collector: PoseCollector,
                 conv: StreamReadings, static_rig: Rig, rate_hz: float, interactive: bool,
                 log: Any, doc: dict[str, Any]) -> tuple[int, Rig]:
    """The geometry from motion (calibration/motion.py) with the joint's zero from the straight
    holds (calibration/reference.py), written to the board: every set_sensor and set_joint,
    the calibrations again, save_eeprom, each calibration read back from EEPROM and the
    board's inventory checked. Returns the exit code and the rig to write (the static
    calibration alone when the motion is refused: that is what the board then holds)."""
    assert stream.link is not None
    log(f"geometry: hold the rig by its links, hinge axis horizontal, and move the joint "
        f"freely for {args.motion_seconds:g} s after a {MOTION_LEAD_IN_S:g} s lead-in — both "
        "links, briskly, both ways, through the joint's range")
    stream.start()
    t, readings = collect_motion(stream, conv, args.motion_seconds, args.pose_timeout,
                                 interactive, log)
    stream.link.command(msgs.StopStream())
    stream.streaming = False
    prior = MotionPrior(position_tol_m=args.position_tolerance_mm * 1e-3,
                        joint_tol_m=args.joint_tolerance_mm * 1e-3,
                        mounting_tol_deg=args.mounting_tolerance_deg)
    motion = calibrate_motion(static_rig.with_sample_rate(rate_hz), t, readings, prior)
    doc["motion"] = motion_doc(motion)
    if not motion.accepted:
        log("geometry from motion rejected: nothing of it written (" + "; ".join(
            motion.reasons) + "); the board and the rig file keep the sensor calibration")
        return 1, static_rig
    fitted = motion_calibrated_rig(static_rig, motion)
    zero = combine_references([measure_reference(fitted, h, 0.0)
                               for h in collector.holds(STRAIGHT_POSES)])
    doc["motion"]["reference"] = reference_doc(zero)
    if not zero.accepted:
        log("the joint's zero from the straight holds was refused: nothing of the geometry "
            "written (" + "; ".join(zero.reasons) + ")")
        return 1, static_rig
    fitted = referenced_rig(fitted, zero)
    for g in motion.sensors:
        log(f"  {g.label}: lever arm {g.lever_m[0] * 1e3:.2f}, {g.lever_m[1] * 1e3:.2f} mm "
            f"(σ along {g.length_sigma_m * 1e3:.2f} mm, grade {g.grade})")
    log(f"  joint's zero: the straight holds read {zero.offset_deg:+.3f}° (σ "
        f"{zero.sigma_deg:.3f}°), removed")
    try:
        commands = rig_commands(fitted)
        for m in commands:
            stream.link.command(m)
        stream.link.command(msgs.SaveEeprom(confirm=SAVE_CONFIRM), timeout_s=SAVE_TIMEOUT_S)
        for m in commands:
            if isinstance(m, msgs.SetCalibration):
                back = read_calibration(stream.link, m.slot)
                if any(getattr(back, f) != getattr(m, f) for f in CALIBRATION_FIELDS):
                    raise ReadbackError(f"slot {m.slot}: the EEPROM's calibration differs "
                                        "after the geometry was written")
        check_inventory(fitted, stream.link.handshake())
    except (ReadbackError, CommandError, LinkTimeoutError, InputError) as exc:
        log(f"the board did not take the geometry: {exc}")
        doc["motion"]["error"] = str(exc)
        return 1, static_rig
    doc["motion"]["written"] = True
    log(f"geometry written to the board ({len(commands)} commands), saved in EEPROM")
    return 0, fitted


def _write_doc(w: SlotWrite) -> dict[str, Any]:
    return {"slot": w.slot, "sensor": w.label, "confirmed": w.confirmed,
            "sent": list(w.sent), "stored": list(w.stored),
            "S": (np.asarray(w.stored[:9], dtype=float) / 2**24).reshape(3, 3).tolist(),
            "offset": [v * 1e-6 for v in w.stored[9:]]}
