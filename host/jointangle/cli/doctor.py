"""`jointangle doctor [--port PORT] [--json]`: what would stop the host talking to a board, and
the fix for each (jointangle.doctor)."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from jointangle.doctor import diagnose

MARK = {"ok": "ok", "problem": "PROBLEM", "note": "note"}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "doctor", help="check the serial port, permissions, ModemManager, avrdude and the "
        "compiled parts, and print the fix for each problem",
        description="Check what commonly stops a board from talking to the host: no board "
        "found (USB VID:PID), not being in the group that owns the serial device, another "
        "program holding the port, ModemManager probing /dev/ttyACM*, avrdude missing for "
        "`flash`; and list which compiled parts (the firmware replay library, the virtual "
        "devices, the virtual boards, the AVR image) are present. Each problem comes with its "
        "fix. Exit status 1 when a problem is found.")
    p.add_argument("--port", metavar="PORT", default=None,
                   help="the serial device to check (default: every board found by USB "
                   "VID:PID)")
    p.add_argument("--json", action="store_true",
                   help='print one JSON object: {"findings": [{"check", "status", "message", '
                   '"fix"}], "problems": N}')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    findings = diagnose(port=args.port)
    problems = sum(f.status == "problem" for f in findings)
    if args.json:
        print(json.dumps({"findings": [asdict(f) for f in findings], "problems": problems}))
    else:
        for f in findings:
            print(f"{MARK[f.status]:8} {f.check:13} {f.message}")
            if f.fix:
                print(f"{'':8} {'':13} fix: {f.fix}")
        print(f"{problems} problem{'s' if problems != 1 else ''} found")
    return 1 if problems else 0
