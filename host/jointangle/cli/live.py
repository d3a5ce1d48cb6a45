"""`jointangle live [--port URL] [--json-lines] [--plot]`: watch the joint angle as it streams."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

from rich.console import Console
from rich.live import Live

from jointangle.cli.common import (
    add_stream_options,
    nonnegative_float,
    nonnegative_int,
    positive_float,
    stream_checks,
)
from jointangle.cli.info import add_port_arguments, launch_options
from jointangle.device.describe import FAULT_NAMES, eeprom_problem, enum_name, hello_record
from jointangle.device.rig import device_rig
from jointangle.errors import InputError
from jointangle.i2c.live import run_i2c_live
from jointangle.live.host_filter import (
    HostEstimate,
    HostFilter,
    choose_host_filter,
    host_filter_help,
    host_filter_name,
    json_fields,
)
from jointangle.live.host_worker import HostLines, HostWorker
from jointangle.live.session import Estimate, LiveState
from jointangle.live.stream import (
    STREAM_CONTENTS,
    DeviceLostError,
    DeviceStream,
    interrupt_flag,
)
from jointangle.live.view import render
from jointangle.model import read_checked_rig
from jointangle.protocol import messages as msgs
from jointangle.recording.jrec import JrecWriter
from jointangle.rig import Rig, parse_rig

REFRESH_S = 0.1


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "live", help="live readout: angle, rates, trace, losses, sensor health, mirror check",
        description="Start the stream and show θ, ω_a, ω_b, a moving trace of θ, the firmware's "
        "divergence from the host mirror filter, the sample rate, frame loss, per-sensor health "
        "and an observability warning. Keys: r starts/stops a recording, q quits. When stdin is "
        "not a terminal it runs for --seconds and prints a line per second.")
    add_port_arguments(p)
    p.add_argument("--i2c", metavar="BUS", default=None,
                   help="no board: read the sensors from this machine's I2C bus with smbus2 "
                   "(BUS = N for /dev/i2c-N, or 'sim' for the virtual devices at 400 kHz) and "
                   "run the calibration and the float EKF here (needs --rig for a real bus)")
    p.add_argument("--rig", type=Path, help="rig file of this build (divergence and "
                   "observability need it); default: the virtual board's own rig")
    p.add_argument("--seconds", type=positive_float, default=None,
                   help="stop after this long (default: until q; 10 s when not interactive)")
    p.add_argument("--json-lines", action="store_true",
                   help="print one JSON object per estimate on stdout (for scripts); "
                   "theta_deg, omega_a_dps and omega_b_dps are the board's, null while the "
                   "board's filter is not running (its health lacks 'running'); host_filter, "
                   "host_theta_deg, host_omega_a_dps, host_omega_b_dps are the host filter's "
                   "estimate of the sample host_lag_ms earlier (its board clock in "
                   "host_device_t), null while it has none (also on lines it could not follow "
                   "within 0.25 s). Lines come in batches of 50 ms while a host filter runs")
    p.add_argument("--host-filter", type=host_filter_name, default=None, metavar="NAME",
                   help=host_filter_help())
    p.add_argument("--json", action="store_true",
                   help="print a JSON summary on stdout at the end")
    p.add_argument("--plot", action="store_true",
                   help="also open a live matplotlib window (needs a display)")
    p.add_argument("--record", type=Path, metavar="FILE.jrec",
                   help="record from the start into this file (key r toggles recordings too)")
    p.add_argument("--record-dir", type=Path, default=Path("."),
                   help="where key r puts its recordings (default: the current directory)")
    p.add_argument("--restart-filter", action=argparse.BooleanOptionalAction, default=True,
                   help="after starting the stream, restart the board's filter with the settings "
                   "it has (restart_filter: nothing else changes) so the firmware-vs-mirror "
                   "divergence (and a recording's replay --verify) follows the filter from its "
                   "first step (default: on; --no-restart-filter leaves the running filter alone "
                   "and the divergence waits for its next start)")
    p.add_argument("--retries", type=nonnegative_int, default=5,
                   help="reconnect attempts after the device is lost (default %(default)s); the "
                   "view says 'reconnecting…' meanwhile, and the board's filter is restarted "
                   "after each reconnect when --restart-filter started it")
    p.add_argument("--retry-delay", type=nonnegative_float, default=0.5, metavar="S",
                   help="seconds between reconnect attempts (default %(default)s)")
    p.add_argument("--stall", type=positive_float, default=2.0, metavar="S",
                   help="no byte for this long while streaming counts as a lost device")
    p.add_argument("--no-mirror", action="store_true",
                   help="do not compute the firmware-vs-mirror divergence (saves CPU)")
    add_stream_options(p)
    p.set_defaults(func=run)


def has_display() -> bool:
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@contextlib.contextmanager
def cbreak(stream: TextIO) -> Iterator[None]:
    """Keys without Enter and without echo, restored on exit (POSIX terminals; Windows' console
    gives `read_key` its keys as they are pressed)."""
    if sys.platform == "win32":
        yield
        return
    import termios  # POSIX only: imported here so that the command line starts on Windows
    import tty

    fd = stream.fileno()
    old = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


def read_key(stream: TextIO) -> str | None:
    """One key if one was pressed, without blocking."""
    if sys.platform == "win32":
        import msvcrt

        return msvcrt.getwch() if msvcrt.kbhit() else None
    if select.select([stream], [], [], 0)[0]:
        return os.read(stream.fileno(), 1).decode(errors="replace")
    return None


class LivePlot:
    """A matplotlib window with θ over the trace window, redrawn from the main loop."""

    def __init__(self) -> None:
        # Deferred: matplotlib (with pyplot ~0.3 s) loads only for --plot, and takes its backend
        # before pyplot is imported.
        import matplotlib

        if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
            with contextlib.suppress(ImportError, ValueError):
                matplotlib.use("TkAgg")
        import matplotlib.pyplot as plt

        if matplotlib.get_backend().lower() == "agg":
            raise InputError("--plot needs an interactive matplotlib backend (e.g. TkAgg); "
                             "only Agg is available", field="--plot")
        self.plt = plt
        plt.ion()
        self.fig, self.ax = plt.subplots(figsize=(8, 4))
        (self.line,) = self.ax.plot([], [], lw=1)
        self.ax.set_xlabel("t (s, device clock)")
        self.ax.set_ylabel("θ (°)")
        self.ax.grid(True)

    def update(self, state: LiveState) -> bool:
        if not self.plt.fignum_exists(self.fig.number):
            return False
        if state.trace:
            t, v = zip(*state.trace, strict=True)
            self.line.set_data(t, v)
            self.ax.relim()
            self.ax.autoscale_view()
        self.plt.pause(0.001)
        return True


def _matching_rig(rig: Rig | None, hello: Any, events: list[str]) -> Rig | None:
    """The rig as the board's filter sees it, or None with a warning when the board is set up
    differently (e.g. it fell back to its defaults after a bad EEPROM checksum): the stream is
    still shown, without the divergence and the observability check that need the rig."""
    if rig is None:
        return None
    try:
        return device_rig(rig, hello)
    except InputError as exc:
        warning = (f"rig not used: {exc.reason} (the divergence and the observability check "
                   "need a rig that matches the board)")
        events.append(warning)
        print(f"jointangle live: warning: {warning}", file=sys.stderr)
        return None


def _new_recording_path(folder: Path) -> Path:
    """jointangle-YYYYMMDD-HHMMSS.jrec in `folder`, with -2, -3, ... when `r` was pressed more
    than once in that second (a second recording used to end the session: it existed)."""
    stem = time.strftime("jointangle-%Y%m%d-%H%M%S")
    path, n = folder / f"{stem}.jrec", 1
    while path.exists():
        n += 1
        path = folder / f"{stem}-{n}.jrec"
    return path


def run(args: argparse.Namespace) -> int:
    if args.i2c is not None:
        # The host reads the sensors itself: no board, stream or recording to apply these to.
        ignored = {"--port": args.port is not None, "--record": args.record is not None,
                   "--no-mirror": args.no_mirror, "--plot": args.plot,
                   "--host-filter": args.host_filter is not None}
        for option, given in ignored.items():
            if given:
                raise InputError("does not apply with --i2c (the host reads the sensors "
                                 "itself: no board stream to record or mirror)", field=option)
        return run_i2c_live(args)
    if args.plot and not has_display():
        raise InputError("--plot needs a display, but neither DISPLAY nor WAYLAND_DISPLAY is "
                         "set (run without --plot, or pipe --json-lines into a plotter)",
                         field="--plot")
    rig_text: str | None = None
    rig_file: Rig | None = None
    if args.rig is not None:
        if not args.rig.is_file():
            raise InputError("rig file not found", path=args.rig)
        # the geometry too (coincident sensors...): the board would reject it and stream zeros
        rig_text, rig_file = read_checked_rig(args.rig)
    interactive = (sys.stdin.isatty() and sys.stdout.isatty() and not args.json_lines
                   and not args.json)
    if interactive and not args.record_dir.is_dir():  # `r` records there
        raise InputError("is not a folder (r records into it)", path=args.record_dir,
                         field="--record-dir")
    seconds = args.seconds if args.seconds is not None else (None if interactive else 10.0)
    events: list[str] = []
    if not stream_checks(args):  # no raw readings every loop: no mirror either
        args.no_mirror = True
    stream = DeviceStream(args.port, baud=args.baud, launch=launch_options(args),
                          handshake_timeout_s=args.timeout, on_event=events.append,
                          retries=args.retries, retry_delay_s=args.retry_delay,
                          stall_s=args.stall, mode=STREAM_CONTENTS[args.stream],
                          every=args.every)
    hello = stream.connect()
    problem = eeprom_problem(hello.eeprom)
    if problem is not None:  # (the interactive view shows it too)
        print(f"jointangle live: warning: {problem}", file=sys.stderr)
    writer: JrecWriter | None = None
    rec_started = 0.0

    def start_recording(path: Path) -> JrecWriter:
        meta: dict[str, Any] = {"hello": hello_record(hello), "port": stream.resolved_url,
                                "host": {"start_unix_ns": time.time_ns()},
                                "stream": {"contents": args.stream, "every": args.every}}
        if rig_text is not None:
            meta["rig"] = rig_text
        w = JrecWriter(path, meta)
        stream.recorder.attach(w)
        events.append(f"recording to {path}")
        return w

    try:
        if rig_text is None and stream.connection is not None and stream.connection.rig_text:
            rig_text = stream.connection.rig_text  # a virtual board's own rig
            rig_file = parse_rig(rig_text, "rig")
        state = LiveState(hello, _matching_rig(rig_file, hello, events),
                          divergence=not args.no_mirror)
        host, host_word = choose_host_filter(args.host_filter, state.rig)
        lines = None if host is None else HostLines(HostWorker(host))
        plot = LivePlot() if args.plot else None
        if args.record is not None:
            writer = start_recording(args.record)
            rec_started = time.monotonic()
        else:
            stream.recorder.attach(None)
    except BaseException:
        stream.stop()  # a virtual board started for this run must not outlive it
        raise
    out = sys.stdout
    t_start = time.monotonic()
    next_refresh = next_line = t_start
    code = 0
    quit_now = False

    console = Console()
    live_ctx: Any = (Live(console=console, auto_refresh=False, screen=False)
                     if interactive else contextlib.nullcontext())
    keys_ctx: Any = cbreak(sys.stdin) if interactive else contextlib.nullcontext()

    def view() -> Any:
        return render(state, port=stream.resolved_url,
                      recording=None if writer is None else writer.path.name,
                      rec_seconds=time.monotonic() - rec_started, stats=stream.stats,
                      interactive=interactive, message=events[-1] if events else None,
                      host=host, host_word=host_word)

    def emit(pairs: list[tuple[Estimate, HostEstimate | None]]) -> None:
        """The board's estimates, each with the host's (--json-lines, the Δθ figures)."""
        if args.json_lines:
            for est, h in pairs:
                out.write(json.dumps({**est.as_dict(), **json_fields(host, h)}) + "\n")
        if host is not None and host.off is not None and host.off not in events:
            events.append(host.off)
            print(f"jointangle live: warning: {host.off}", file=sys.stderr)

    def take(ests: list[Estimate]) -> None:
        emit([(e, None) for e in ests] if lines is None else lines.feed(ests))

    try:
        stream.start()
        if args.restart_filter:
            stream.restart_filter()
        with interrupt_flag() as interrupted, live_ctx as live, keys_ctx:
            while not quit_now:
                if interrupted():
                    code = 130
                    break
                now = time.monotonic()
                if seconds is not None and now - t_start >= seconds:
                    break
                take(state.feed(stream.poll()))
                if now >= next_refresh:
                    next_refresh = now + REFRESH_S
                    state.refresh()
                    if args.json_lines:
                        out.flush()
                    if interactive:
                        live.update(view(), refresh=True)
                    if plot is not None and not plot.update(state):
                        plot = None
                if not interactive and not args.json_lines and not args.json \
                        and now >= next_line:
                    next_line = now + 1.0
                    out.write(_line(state, stream.stats, host) + "\n")
                    out.flush()
                key = read_key(sys.stdin) if interactive else None
                if key in ("q", "Q"):
                    quit_now = True
                elif key in ("r", "R"):
                    if writer is None:
                        try:
                            writer = start_recording(_new_recording_path(args.record_dir))
                            rec_started = time.monotonic()
                        except InputError as exc:  # shown in the view; streaming goes on
                            events.append(f"cannot record: {exc}")
                    else:
                        stream.recorder.attach(None)
                        writer.close()
                        events.append(f"saved {writer.path}")
                        writer = None
    except KeyboardInterrupt:
        code = 130
    except DeviceLostError as exc:
        # One line on stderr: stdout carries --json / --json-lines.
        print(f"jointangle live: {exc}", file=sys.stderr)
        code = 1
    finally:
        take(state.feed(stream.stop()))
        if lines is not None:
            emit(lines.finish())
        out.flush()
        if writer is not None:
            writer.close()
    if state.worker is not None and args.json:
        state.refresh()
        state.worker.wait()
    summary = {**state.summary(stream.stats), "port": stream.resolved_url,
               "eeprom": enum_name(msgs.EepromState, hello.eeprom),
               "disconnects": stream.disconnects, "reconnects": stream.reconnects,
               "host_filter": None if host is None or lines is None else {
                   **host.summary(), "lines_without_host": lines.without_host},
               "versions_seen": stream.versions_seen, "events": events,
               "seconds": round(time.monotonic() - t_start, 3)}
    if args.json:
        out.write(json.dumps(summary) + "\n")
    elif not args.json_lines:
        out.write(_line(state, stream.stats, host) + "\n")
    return code


def _line(state: LiveState, stats: dict[str, int], host: HostFilter | None = None) -> str:
    s = state.summary(stats)
    e = state.latest
    head = ("no estimate yet" if e is None else
            f"t {e.t_s:7.2f} s  filter stopped (θ, ω unknown)" if not e.running else
            f"t {e.t_s:7.2f} s  θ {e.theta_deg:8.3f}°  ω_a {e.omega_a_dps:7.2f} °/s  "
            f"ω_b {e.omega_b_dps:7.2f} °/s")
    div = ("" if s["max_abs_dtheta_deg"] is None else
           f"  |Δθ|max {s['max_abs_dtheta_deg']:.4f}°")
    bad = [f"{i}:{','.join(f)}" for i, f in enumerate(s["sensors"])
           if set(f) & set(FAULT_NAMES)]
    obs = "  NOT OBSERVABLE" if s["observable"] is False else ""
    h = None if host is None else host.latest
    hf = ("" if h is None or host is None else
          f"  {host.name} θ {h.theta_deg:8.3f}° ({host.lag_ms:g} ms behind)")
    return (f"{head}{hf}  {s['sample_rate_hz']:.0f} Hz  lost {s['frames_lost']}{div}"
            f"  sensors {'; '.join(bad) if bad else 'ok'}{obs}")
