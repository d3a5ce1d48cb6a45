"""`jointangle info --port URL [--json]`: shake hands with a device and show what it is."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from jointangle.boards.options import (
    DEFAULT_BAUD,
    MAX_MOTION_SECONDS,
    MIN_SIM_BAUD,
    SIM_PREFIX,
    LaunchOptions,
    sim_query_help,
)
from jointangle.cli.common import (
    add_stream_options,
    nonnegative_int,
    positive_float,
    positive_int,
)
from jointangle.device.describe import hello_doc
from jointangle.errors import InputError
from jointangle.live.stream import STREAM_CONTENTS, DeviceStream
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.link import BUS_BOUND
from jointangle.protocol.messages import PROTOCOL_VERSION, SCHEMA_HASH
from jointangle.transport import detect_boards, list_ports_doc


def add_port_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", metavar="URL", default=None,
                   help="serial port or pyserial URL (/dev/ttyACM0, /dev/pts/N, loop://, "
                   "socket://HOST:PORT) or a virtual board (sim://native, sim://avr, "
                   "sim://pico); default: the first Arduino Mega or USB-serial bridge found, "
                   "else sim://native. "
                   "A virtual board takes options as a query, sim://native?KEY=VALUE&...: "
                   + sim_query_help().replace("%", "%%"))
    p.add_argument("--baud", type=positive_int, default=DEFAULT_BAUD,
                   help="baud rate (default %(default)s, the Mega's; a Raspberry Pi Pico streams "
                   "at 1000000)")
    p.add_argument("--timeout", type=positive_float, default=1.0, metavar="S",
                   help="seconds to wait for each answer (default %(default)s)")
    p.add_argument("--scenario", default="gravity-slow-periodic",
                   help="sim:// boards: the motion they play (default %(default)s)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="sim:// boards: noise seed")
    p.add_argument("--sim-seconds", type=positive_float, default=60.0, metavar="S",
                   help="sim:// boards: seconds of motion to generate; the board plays it in a "
                   "loop (default %(default)s: whole periods of the periodic scenarios)")


def launch_options(args: argparse.Namespace) -> LaunchOptions:
    """What a sim:// board is started with, from the common port arguments."""
    rig = getattr(args, "rig", None)
    port = getattr(args, "port", None)
    if port is None or str(port).startswith(SIM_PREFIX):  # (no port: perhaps sim://native)
        # The limits of the sim:// query's baud= and seconds=, before a board is started.
        if args.baud < MIN_SIM_BAUD:
            raise InputError(f"a virtual board runs at {MIN_SIM_BAUD} baud or more",
                             field="--baud")
        if args.sim_seconds > MAX_MOTION_SECONDS:
            raise InputError(f"at most {MAX_MOTION_SECONDS:g} s of motion",
                             field="--sim-seconds")
    return LaunchOptions(scenario=args.scenario, seed=args.seed, rig_path=rig, baud=args.baud,
                         seconds=args.sim_seconds)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "info", help="handshake with a device: firmware, protocol, schema, board, sensors",
        description="Send get_info and print the device's hello: firmware and protocol version, "
        "schema hash, build, board, sample rate, EEPROM state and the sensor inventory with the "
        "chip IDs read from the chips. A device speaking another protocol version or built from "
        "another schema is refused with a message naming both.")
    add_port_arguments(p)
    p.add_argument("--list", action="store_true",
                   help="list serial ports and the known boards among them; no handshake")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--rates", action="store_true",
                   help="also stream for a moment (~1.5 s) and report the loop rate the board "
                   "achieves and the highest rate it says it sustains at >= 20 %% asleep with its "
                   "sensors, filter and the stream chosen by --stream/--every, beside the "
                   "configured rate")
    add_stream_options(p)
    p.set_defaults(func=run)


RATES_TIMEOUT_S = 4.0  # the board measures over 1 s windows: a figure within two of them


def measured_rates(stream: DeviceStream, contents: str = "full",
                   every: int = 1) -> dict[str, int | None]:
    """Stream `contents` (STREAM_CONTENTS) every `every` loops with status every 200 ms until a
    status carries the board's own figures (loop rate, sustainable rate), then stop:
    {achieved_rate_hz, sustainable_rate_hz}."""
    assert stream.link is not None
    link = stream.link
    link.command(msgs.StartStream(mode=STREAM_CONTENTS[contents], status_interval_ms=200,
                                  every=every))
    best: dict[str, int | None] = {"achieved_rate_hz": None, "sustainable_rate_hz": None}
    deadline = time.monotonic() + RATES_TIMEOUT_S
    try:
        while time.monotonic() < deadline and best["sustainable_rate_hz"] is None:
            for fr in link.poll():
                if fr.msg_id != msgs.Status.MSG_ID:
                    continue
                st = decode_message(fr)
                assert isinstance(st, msgs.Status)
                if st.loop_rate_hz and st.sustainable_rate_hz:
                    best = {"achieved_rate_hz": int(st.loop_rate_hz),
                            "sustainable_rate_hz": int(st.sustainable_rate_hz)}
    finally:
        link.command(msgs.StopStream())
    return best


def stream_words(contents: str, every: int) -> str:
    """'full stream', 'estimates stream every 4th loop', ..."""
    return f"{contents} stream" + (f" every {every}th loop" if every > 1 else "")


def run(args: argparse.Namespace) -> int:
    if args.list:
        doc: dict[str, Any] = {"ports": list_ports_doc(),
                               "boards": [b.device for b in detect_boards()]}
        if args.json:
            sys.stdout.write(json.dumps(doc) + "\n")
        else:
            for p in doc["ports"]:
                print(f"{p['device']}  {p['vid'] or '----'}:{p['pid'] or '----'}  "
                      f"{p['known'] or ''}")
            if not doc["ports"]:
                print("no serial ports")
        return 0
    stream = DeviceStream(args.port, baud=args.baud, handshake_timeout_s=args.timeout,
                          launch=launch_options(args))
    hello = stream.connect()
    url = stream.resolved_url
    try:
        rates = measured_rates(stream, args.stream, args.every) if args.rates else None
    finally:
        stream.stop()
    doc = {"port": url, **hello_doc(hello),
           "host_protocol_version": PROTOCOL_VERSION, "host_schema_hash": f"0x{SCHEMA_HASH:08X}"}
    if rates is not None:
        doc.update(rates)
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
        return 0
    print(f"{url}: jointangle firmware {doc['firmware_version']} (build {doc['build'] or '?'}) "
          f"on {doc['board']}")
    print(f"  protocol {doc['protocol_version']}, schema {doc['schema_hash']} (matches this host)")
    print(f"  sample rate {doc['sample_rate_hz']} Hz, EEPROM {doc['eeprom']}, streaming "
          f"{', '.join(doc['stream_mode']) or 'off'}")
    if rates is not None:
        print(f"  rates: configured {doc['sample_rate_hz']} Hz, achieved "
              f"{rates['achieved_rate_hz'] or '?'} Hz, sustainable "
              f"{rates['sustainable_rate_hz'] or '?'} Hz (>= 20 % asleep, {BUS_BOUND}, "
              f"{stream_words(args.stream, args.every)})")
    if doc["eeprom_warning"]:
        print(f"  warning: {doc['eeprom_warning']}")
    for i, s in enumerate(doc["sensors"]):
        mux = "direct" if s["mux_channel"] is None else f"mux {s['mux_channel']}"
        print(f"  sensor {i}: link {s['link']} {s['model']} ±{s['range_g']} g at {s['address']} "
              f"({mux}), chip id {s['chip_id']}, read {s['read_delay_us']} µs after the first, "
              f"{', '.join(s['status']) if s['status'] else 'ok'}")
    return 0
