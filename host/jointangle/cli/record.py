"""`jointangle record --port URL --seconds S --out FILE.jrec`: record a device's stream."""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from jointangle import __version__
from jointangle.cli.common import (
    add_stream_options,
    nonnegative_float,
    nonnegative_int,
    positive_float,
    refuse_overwrite,
    stream_checks,
)
from jointangle.cli.info import add_port_arguments, launch_options
from jointangle.device.describe import eeprom_problem, enum_name, hello_record
from jointangle.device.rig import device_rig
from jointangle.errors import InputError
from jointangle.live.host_filter import (
    HostFilter,
    choose_host_filter,
    host_filter_help,
    host_filter_name,
)
from jointangle.live.host_worker import HostWorker
from jointangle.live.session import LiveState
from jointangle.live.stream import (
    STREAM_CONTENTS,
    DeviceLostError,
    DeviceStream,
    interrupt_flag,
)
from jointangle.model import read_checked_rig
from jointangle.protocol import messages as msgs
from jointangle.recording.jrec import JrecWriter
from jointangle.rig import Rig, parse_rig


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "record", help="record a device's stream to a .jrec file",
        description="Shake hands, start the stream and write every byte exactly as received, "
        "with host receive times, to a .jrec recording whose metadata holds the rig, the hello "
        "and the host. Ctrl-C stops cleanly; a pulled cable keeps the file valid up to the last "
        "byte and the host tries to reconnect (--retries), appending to the same file.")
    add_port_arguments(p)
    p.add_argument("--seconds", type=positive_float, required=True, help="how long to record")
    p.add_argument("--out", type=Path, required=True, help="recording to create (.jrec)")
    p.add_argument("--rig", type=Path, help="the rig file of this build (kept in the recording; "
                   "replay --verify needs it); default: the virtual board's own rig")
    p.add_argument("--overwrite", action="store_true", help="replace an existing recording")
    p.add_argument("--restart-filter", action=argparse.BooleanOptionalAction, default=True,
                   help="after starting the stream, restart the board's filter with the settings "
                   "it has (restart_filter: nothing else changes) so the recording holds the "
                   "filter from its first step and replay --verify can check all of it "
                   "(default: on, as in live; --no-restart-filter leaves a running filter alone)")
    p.add_argument("--retries", type=nonnegative_int, default=5,
                   help="reconnect attempts after the device is lost (default %(default)s)")
    p.add_argument("--retry-delay", type=nonnegative_float, default=0.5, metavar="S",
                   help="seconds between reconnect attempts (default %(default)s)")
    p.add_argument("--stall", type=positive_float, default=2.0, metavar="S",
                   help="no byte for this long while streaming counts as a lost device")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    add_stream_options(p)
    p.add_argument("--host-filter", type=host_filter_name, default=None, metavar="NAME",
                   help=host_filter_help("sum it up at the end (host_filter: its CPU time per "
                                         "sample, backlog, last θ and its difference from the "
                                         "board's θ)") + ". The recording holds the board's "
                   "bytes only: replay --estimates-csv --host-filter NAME recomputes any host "
                   "filter from it")
    p.set_defaults(func=run)


def host_summary_line(host: HostFilter) -> str:
    s = host.summary()
    if s["switched_off"]:
        return s["switched_off"]
    theta = "no estimate" if s["theta_deg"] is None else f"last θ {s['theta_deg']:.3f}°"
    diff = ("" if s["host_minus_board_rms_deg"] is None else
            f"; host − board θ RMS {s['host_minus_board_rms_deg']:.4f}° (max "
            f"{s['host_minus_board_max_abs_deg']:.4f}°) after each start's first 2 s")
    return (f"host {s['name']} ({s['lag_ms']:g} ms lag): {s['estimates']} of {s['samples']} "
            f"samples, {theta}; CPU {s['cpu_per_sample_ms']:.3f} ms a sample "
            f"({s['cpu_load']:.0%} of the period), backlog at most {s['backlog_max_s']:.2f} s"
            f"{diff}")


def _progress(total_s: float, enabled: bool) -> Any:
    return Progress(TextColumn("recording"), BarColumn(), TextColumn("{task.fields[info]}"),
                    TimeRemainingColumn(), console=Console(stderr=True), disable=not enabled,
                    transient=True)


def _host_filter(name: str | None, rig_text: str | None, hello: msgs.Hello
                 ) -> tuple[HostFilter | None, str]:
    """choose_host_filter on the rig as the board sees it; a rig that does not match the
    board switches the default off (with a warning) and refuses a filter asked for by name."""
    rig: Rig | None = None
    if rig_text is not None:
        try:
            rig = device_rig(parse_rig(rig_text, "rig"), hello)
        except InputError as exc:
            if name is not None:
                raise InputError(f"{name} needs a rig that matches the board: {exc.reason}",
                                 field="--host-filter") from None
            print(f"jointangle record: warning: host filter off: {exc.reason}",
                  file=sys.stderr)
    return choose_host_filter(name, rig)


# The per-loop frames a sample is counted from (--stream full or estimates).
ESTIMATE_IDS = frozenset((msgs.SampleEstimate.MSG_ID, msgs.LeanEstimate.MSG_ID))


def run(args: argparse.Namespace) -> int:
    refuse_overwrite({"--rig": args.rig}, {"--out": args.out})
    if args.out.is_dir():
        raise InputError("is a directory: name the recording file to create", path=args.out)
    if args.out.exists() and not args.overwrite:
        raise InputError("recording already exists (use --overwrite)", path=args.out)
    rig_text = None
    if args.rig is not None:
        rig_text, _ = read_checked_rig(args.rig)  # refuse a bad rig (or geometry) first
    events: list[str] = []
    stream_checks(args)  # a thinned stream: no host filter
    stream = DeviceStream(args.port, baud=args.baud, launch=launch_options(args),
                          mode=STREAM_CONTENTS[args.stream], every=args.every,
                          retries=args.retries,
                          retry_delay_s=args.retry_delay,
                          stall_s=args.stall, on_event=events.append,
                          handshake_timeout_s=args.timeout)
    hello = stream.connect()
    problem = eeprom_problem(hello.eeprom)
    if problem is not None:  # (the interactive view shows it too)
        print(f"jointangle record: warning: {problem}", file=sys.stderr)
    if rig_text is None and stream.connection is not None:
        rig_text = stream.connection.rig_text
    meta: dict[str, Any] = {
        "hello": hello_record(hello), "port": stream.resolved_url,
        "host": {"name": socket.gethostname(), "jointangle": __version__,
                 "start_unix_ns": time.time_ns()},
        "stream": {"contents": args.stream, "every": args.every},
    }
    if rig_text is not None:
        meta["rig"] = rig_text
    try:
        host, _ = _host_filter(args.host_filter, rig_text, hello)
        state = LiveState(hello, None, divergence=False) if host is not None else None
        worker = None if host is None else HostWorker(host)
        writer = JrecWriter(args.out, meta, overwrite=args.overwrite)
    except BaseException:
        stream.stop()  # a virtual board started for this run must not outlive it
        raise
    stream.recorder.attach(writer)
    interrupted = False
    lost: str | None = None
    t_start = time.monotonic()
    samples = 0
    try:
        stream.start()
        if args.restart_filter:
            stream.restart_filter()
        with interrupt_flag() as stop_asked, \
                _progress(args.seconds, sys.stderr.isatty() and not args.json) as bar:
            task = bar.add_task("rec", total=args.seconds, info="")
            while (elapsed := time.monotonic() - t_start) < args.seconds:
                if stop_asked():
                    interrupted = True
                    break
                frames = stream.poll()
                for fr in frames:
                    samples += fr.msg_id in ESTIMATE_IDS
                if worker is not None and state is not None:
                    worker.add(state.feed(frames))
                    worker.take()  # only the summary is kept
                st = stream.stats
                bar.update(task, completed=elapsed,
                           info=f"{samples} samples, {st.get('frames_lost', 0)} lost, "
                                f"{st.get('crc_errors', 0)} crc")
    except KeyboardInterrupt:
        interrupted = True
    except DeviceLostError as exc:
        lost = str(exc)
    finally:
        left = []
        try:
            left = stream.stop()
            samples += sum(fr.msg_id in ESTIMATE_IDS for fr in left)
        finally:
            writer.close()
        t_end = time.monotonic()  # (the host filter may still have samples to go through)
        if worker is not None and state is not None:
            worker.add(state.feed(left))
            worker.finish()
    doc = {"out": str(args.out), "port": stream.resolved_url,
           "eeprom": enum_name(msgs.EepromState, hello.eeprom),
           "seconds": round(t_end - t_start, 3), "records": writer.records,
           "bytes": writer.bytes, "samples": samples, **stream.summary(),
           "interrupted": interrupted, "complete": not interrupted and lost is None,
           "events": events, "host_filter": None if host is None else host.summary()}
    if lost is not None:
        doc["error"] = lost
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
    else:
        print(f"{args.out}: {doc['bytes']} bytes, {samples} samples in {doc['seconds']:.1f} s; "
              f"{doc['frames_lost']} frames lost, {doc['crc_errors']} CRC errors, "
              f"{doc['disconnects']} disconnects ({doc['reconnects']} reconnected)")
        if host is not None:
            print(host_summary_line(host))
    if lost is not None:
        print(f"jointangle record: {lost}; the recording is valid up to the last byte received",
              file=sys.stderr)
        return 1
    return 130 if interrupted else 0
