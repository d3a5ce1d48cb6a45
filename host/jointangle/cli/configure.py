"""`jointangle configure`: give a board its rig (geometry, calibrations) and its loop rate, and
keep them (save_eeprom) — what a user of their own build does once before `live` or `record`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from jointangle.cli.common import add_stream_options, positive_int
from jointangle.cli.info import add_port_arguments, launch_options, measured_rates
from jointangle.device.configure import SAVE_CONFIRM, SAVE_TIMEOUT_S, rig_commands
from jointangle.device.describe import hello_doc
from jointangle.device.rig import check_inventory
from jointangle.errors import InputError
from jointangle.io.rig_file import load_rig
from jointangle.live.stream import DeviceStream
from jointangle.protocol import messages as msgs
from jointangle.protocol.link import BUS_BOUND, CommandError, refusal_reason

RATE_RANGE_HZ = (10, 1000)  # set_rate's range (APP.md)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "configure", help="give a board its rig and loop rate, and save them in its EEPROM",
        description="Send a board the geometry of a rig file (every sensor: link, part, "
        "multiplexer channel, address, range, position and mounting rotation; each link's joint; "
        "the calibrations the file carries) and/or a loop rate, then with --save keep them in "
        "its EEPROM. A rate above what the board says it sustains at >= 20 %% asleep with its "
        "sensors, filter and stream is refused naming that rate, unless --force (the board then "
        "loops as fast as its work allows and counts overruns); the board measures that rate "
        "over a second of the stream given by --stream/--every before the rate is sent. Prints "
        "the board's hello after.")
    add_port_arguments(p)
    p.add_argument("--rig", type=Path, help="the rig file of this build (TOML)")
    p.add_argument("--rate", type=positive_int, metavar="HZ",
                   help=f"loop rate, {RATE_RANGE_HZ[0]}-{RATE_RANGE_HZ[1]} Hz")
    p.add_argument("--force", action="store_true",
                   help="set --rate even above the rate the board says it sustains")
    add_stream_options(p)  # what the rate is judged with
    p.add_argument("--save", action="store_true",
                   help="save the configuration in the board's EEPROM (else it lasts until reset)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run)


def _refused(what: str, err: CommandError) -> InputError:
    if err.code == msgs.ErrorCode.RATE_NOT_SUSTAINABLE:
        return InputError(f"the board refused {what}: it holds at most {err.detail} Hz at "
                          ">= 20 % asleep with its sensors, filter and stream, its "
                          f"{BUS_BOUND}; ask for "
                          f"{err.detail} Hz or less, or add --force", field="--rate")
    return InputError(f"the board refused {what}: {refusal_reason(err.code, err.detail)}",
                      field="--rate" if what.startswith("set_rate") else "--rig")


def run(args: argparse.Namespace) -> int:
    if args.rig is None and args.rate is None and not args.save:
        raise InputError("nothing to do: give --rig, --rate and/or --save", field="--rig")
    if args.force and args.rate is None:
        raise InputError("--force goes with --rate", field="--force")
    if args.rate is not None and not RATE_RANGE_HZ[0] <= args.rate <= RATE_RANGE_HZ[1]:
        raise InputError(f"--rate {args.rate}: the board takes {RATE_RANGE_HZ[0]}-"
                         f"{RATE_RANGE_HZ[1]} Hz", field="--rate")
    rig = load_rig(args.rig) if args.rig is not None else None  # bad files refused before a port
    stream = DeviceStream(args.port, baud=args.baud, handshake_timeout_s=args.timeout,
                          launch=launch_options(args))
    hello = stream.connect()
    link = stream.link
    assert link is not None
    done: list[str] = []
    forced = False  # a rate set above what the board said it sustains
    try:
        link.command(msgs.StopStream())  # the board takes configuration between streams
        if rig is not None:
            for m in rig_commands(rig):
                try:
                    link.command(m)
                except CommandError as err:
                    raise _refused(f"{m.NAME} {m}", err) from None
            done.append(f"rig {rig.name}")
        if args.rate is not None:
            # The board judges a rate by its own measure of a second of loops (0 until then:
            # it would take anything), with the sensors just configured and the stream to come.
            sustainable = measured_rates(stream, args.stream, args.every)["sustainable_rate_hz"]
            try:
                link.command(msgs.SetRate(rate_hz=args.rate, force=int(args.force)))
            except CommandError as err:
                raise _refused(f"set_rate {args.rate} Hz", err) from None
            forced = sustainable is None or args.rate > sustainable
            done.append(f"rate {args.rate} Hz" + (" (forced)" if forced else ""))
        if args.save:
            try:
                link.command(msgs.SaveEeprom(confirm=SAVE_CONFIRM), timeout_s=SAVE_TIMEOUT_S)
            except CommandError as err:
                raise _refused("save_eeprom", err) from None
            done.append("saved in EEPROM")
        hello = link.handshake()
        if rig is not None:
            check_inventory(rig, hello)  # the board now lists what the rig says
    finally:
        stream.stop()
    doc: dict[str, Any] = {"port": stream.resolved_url, "done": done, "forced": forced,
                           **hello_doc(hello)}
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
        return 0
    print(f"{doc['port']}: {', '.join(done) or 'nothing changed'}")
    print(f"  sample rate {doc['sample_rate_hz']} Hz, {len(doc['sensors'])} sensors, EEPROM "
          f"{doc['eeprom']}")
    if forced:
        print("  forced, above the rate the board sustains: it loops as fast as its work allows "
              "and counts overruns (jointangle info --rates shows achieved and sustainable)")
    return 0
