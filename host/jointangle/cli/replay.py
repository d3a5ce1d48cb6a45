"""`jointangle replay FILE.jrec`: decode a recording as it was received; counts, CSV export and
(with --verify) the firmware's estimates against the host's float `mirror` filter."""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointangle.cli.common import refuse_overwrite
from jointangle.device.verify import starts_stream, unseen_before, verify_columns
from jointangle.errors import InputError
from jointangle.estimators.mirror import find_replay_library
from jointangle.estimators.registry import get_estimator
from jointangle.io.atomic import check_output_paths
from jointangle.model import read_checked_rig
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.codec import SPECS_BY_ID
from jointangle.protocol.framing import Frame, StreamDecoder
from jointangle.recording.export import (
    CsvTable,
    accelerations_table,
    estimates_table,
    find_hello,
)
from jointangle.recording.firmware_verify import compare_columns
from jointangle.recording.host_columns import COLUMNS, host_columns
from jointangle.recording.jrec import JrecReader
from jointangle.recording.stream_export import StreamExport
from jointangle.recording.stream_verify import StreamVerifier
from jointangle.rig import Rig, parse_rig


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "replay", help="decode a .jrec recording: frames, losses, damage; export CSVs",
        description="Feed a recording through the streaming decoder exactly as it was received "
        "and report what arrived: frames, frames lost (sequence gaps), CRC errors and bytes "
        "skipped. A recording cut short (a kill, a pulled cable) is read up to its last byte.")
    p.add_argument("file", type=Path, help="recording (.jrec)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--verify", action="store_true",
                   help="recompute the estimates with the host float mirror of the firmware "
                   "filter and report the largest and RMS angle difference")
    p.add_argument("--verify-firmware", action="store_true",
                   help="re-run the recorded counts through the x86 build of the firmware's "
                   "fixed-point core from each filter start and count the frames whose streamed "
                   "theta, omega_a or omega_b differ from it by even one bit (library: "
                   "$JOINTANGLE_FIRMWARE_LIB or CMake target ja_filter_replay)")
    p.add_argument("--rig", type=Path, metavar="RIG.toml",
                   help="the rig file of this build, for --verify*, --host-filter and the "
                   "export when the recording's metadata is damaged or has none (it replaces "
                   "the metadata's rig)")
    p.add_argument("--accel-csv", type=Path, metavar="OUT.csv",
                   help="also write the accelerations CSV (m/s², sensor frames)")
    p.add_argument("--estimates-csv", type=Path, metavar="OUT.csv",
                   help="also write the firmware's estimates CSV")
    p.add_argument("--host-filter", metavar="NAME",
                   help="add a host estimator's columns to --estimates-csv (host_theta_deg, "
                   "host_omega_a_dps, host_omega_b_dps), computed from the raw counts in the "
                   "board's sample_estimate frames with the recording's rig: any filter of "
                   "estimate --filter that needs accelerations only (offline ones such as "
                   "array-rts too: the recording is whole). Each run of frames one period "
                   "apart with nothing lost and the same usable sensors is estimated on its "
                   "own; rows without an estimate are empty (NaN)")
    p.set_defaults(func=run)


def summarize(rec: JrecReader, sink: Callable[[Frame], None] | None = None) -> dict[str, Any]:
    """Replay the recorded chunks through the streaming decoder and count what arrived, in one
    pass holding nothing per frame (a lazy reader's recording of any length); every frame
    delivered also goes to `sink` (the streaming --verify)."""
    dec = StreamDecoder()
    per_type: Counter[str] = Counter()
    first_t: int | None = None
    last_t = 0
    prev_t = 0
    wraps = 0  # the device clock's 32-bit wraps so far (as unwrap_us counts them)
    host: list[int] = []  # first and last receive time
    for chunk in rec.chunks():
        if not host:
            host.append(chunk.host_ns)
        last_host = chunk.host_ns
        for fr in dec.feed(chunk.data):
            spec = SPECS_BY_ID.get(fr.msg_id)
            per_type[spec.name if spec else f"0x{fr.msg_id:02X}"] += 1
            if first_t is not None and fr.t_us - prev_t < -(1 << 31):
                wraps += 1
            prev_t = fr.t_us
            last_t = fr.t_us + (wraps << 32)
            if first_t is None:
                first_t = last_t
            if sink is not None:
                sink(fr)
    dec.finish()
    if host:
        host.append(last_host)
    st = dec.stats
    return {
        "frames": st.frames,
        "frames_lost": st.frames_lost,
        "duplicates": st.duplicates,
        "out_of_order": st.out_of_order,
        "stale": st.stale,
        "segments": st.segments,
        "crc_errors": st.crc_errors,
        "bytes_skipped": st.bytes_skipped,
        "malformed": st.malformed,
        "oversize": st.oversize,
        "version_errors": st.version_errors,
        "schema_errors": st.schema_errors,
        "unknown_messages": st.unknown_messages,
        "versions_seen": st.versions_json(),
        "pending_bytes": dec.pending_bytes,
        "truncated_bytes": rec.truncated_bytes,
        "format_version": rec.format_version,
        "metadata_source": rec.metadata_source,
        "file_damage": list(rec.damage),
        "damaged_records": rec.damaged_records,
        "records": rec.record_count,
        "device_seconds": 0.0 if first_t is None else (last_t - first_t) / 1e6,
        "host_seconds": (host[-1] - host[0]) / 1e9 if host else 0.0,
        "messages": dict(sorted(per_type.items())),
    }


def recording_rig(rec: JrecReader, option: str) -> Rig:
    """The rig in the recording's metadata (or given with --rig), parsed."""
    rig_text = rec.metadata.get("rig")
    if not isinstance(rig_text, str):
        raise InputError(f"{option} needs the rig file, but the recording's metadata has no "
                         "'rig' entry (give it with --rig)", path=rec.path, field="rig")
    return parse_rig(rig_text, f"{rec.path}:metadata.rig")


@dataclass(frozen=True)
class _EstimateInputs:
    rig: Rig
    hello: Any
    cols: dict[str, np.ndarray]
    lost_before: np.ndarray  # nonzero: steps unseen before the frame (device.verify.unseen_before)


def _estimate_inputs(rec: JrecReader, option: str) -> _EstimateInputs:
    """The rig, hello, sample_estimate columns and per-frame losses --verify* need."""
    rig = recording_rig(rec, option)
    result = bulk_decode(rec.data())
    hello = find_hello(result, rec.metadata)
    if hello is None:
        raise InputError(f"{option} needs the sensor inventory (hello)", path=rec.path)
    if not (result.msg_id == 0x04).any():
        raise InputError(f"{option} needs sample_estimate frames (firmware estimates with the "
                         "samples they came from)", path=rec.path)
    cols = result.columns("sample_estimate")
    acks = result.columns("ack")
    started = np.zeros(len(result), dtype=bool)
    started[acks["index"][starts_stream(acks["command_id"], acks["error"])]] = True
    # A run is not followed across a gap or a stream start (device.verify: unseen_before).
    lost_before = unseen_before(result.seq, started, cols["index"])
    return _EstimateInputs(rig, hello, cols, lost_before)


def _no_start(rec: JrecReader, option: str, what: str) -> InputError:
    return InputError("no filter start (health 'reset') in the recording: the firmware's "
                      f"filter started before the recording did, so {what} cannot follow "
                      "it; record with --restart-filter (or from a board start)",
                      path=rec.path, field=option)


def verify(rec: JrecReader) -> dict[str, Any]:
    """Firmware θ against the host `mirror` filter on the same recorded (quantised) inputs.

    Needs the rig (metadata "rig", TOML text), the sensor inventory (hello) and sample_estimate
    frames. The counts become the firmware's own Q15.16 link-frame readings (its float32
    calibration map, `jointangle.device`), `mirror` runs on them with the firmware's noise
    model and rate from each filter start (health `reset`) for as long as no frame is missing;
    θ differences are wrapped to ±180°. Frames before the first start in the recording, or after
    a gap or a stream start (until the next filter start), cannot be followed and are counted as
    `unverified_frames`.
    """
    inp = _estimate_inputs(rec, "--verify")
    try:
        res = verify_columns(inp.rig, inp.hello, inp.cols, inp.lost_before)
    except InputError as exc:
        raise InputError(exc.reason, path=rec.path, field=exc.field) from None
    if res.verified_frames == 0:
        raise _no_start(rec, "--verify", "`mirror`")
    return res.as_dict()


def verify_firmware(rec: JrecReader) -> dict[str, Any]:
    """The board's streamed θ, ω_a, ω_b against the x86 fixed-point core, bit for bit
    (`jointangle.recording.firmware_verify`): the same segments as --verify, the counts
    calibrated as the app does, the core run from each filter start."""
    inp = _estimate_inputs(rec, "--verify-firmware")
    rate = int(inp.hello.sample_rate_hz) or round(inp.rig.sample_rate_hz)
    try:
        res = compare_columns(inp.rig, inp.hello, rate, inp.cols, inp.lost_before,
                              find_replay_library())
    except InputError as exc:
        raise InputError(exc.reason, path=rec.path, field=exc.field) from None
    if res.frames_compared == 0:
        raise _no_start(rec, "--verify-firmware", "the x86 core")
    doc = res.as_dict()
    doc["firmware_rate_hz"] = rate
    return doc


def _export(rec: JrecReader, args: argparse.Namespace, doc: dict[str, Any]) -> dict[str, int]:
    """Write the CSVs asked for, each whole or not at all, and only once every one of them
    has been built (a recording without estimates writes no accelerations CSV either)."""
    tables: list[tuple[str, Path, CsvTable]] = []
    if args.accel_csv is not None:
        tables.append(("accel_rows", args.accel_csv, accelerations_table(rec)))
    if args.estimates_csv is not None:
        table = estimates_table(rec) if args.host_filter is None else _with_host(rec, args, doc)
        tables.append(("estimate_rows", args.estimates_csv, table))
    return {key: table.write(out) for key, out, table in tables}


def _with_host(rec: JrecReader, args: argparse.Namespace, doc: dict[str, Any]) -> CsvTable:
    """The estimates CSV of the sample_estimate frames with the host filter's columns."""
    inp = _estimate_inputs(rec, "--host-filter")
    try:
        host = host_columns(inp.rig, inp.hello, inp.cols, inp.lost_before, args.host_filter)
    except InputError as exc:
        raise InputError(exc.reason, path=rec.path, field=exc.field or "--host-filter") \
            from None
    table = estimates_table(rec, sources=("sample_estimate",))
    doc.update({"host_filter": host.name, "host_segments": host.segments,
                "host_refused": host.refused,
                "host_rows": int(np.isfinite(host.values[:, 0]).sum())})
    return CsvTable((*table.header, *COLUMNS), np.hstack([table.rows, host.values]))


def _supply_rig(rec: JrecReader, rig: Path | None) -> str | None:
    """Put --rig's text in the metadata (checked first, as record does); where the rig comes
    from: "--rig", "metadata", "metadata copy" (the first was damaged) or None."""
    if rig is not None:
        rec.metadata["rig"], _ = read_checked_rig(rig)
        return "--rig"
    if not isinstance(rec.metadata.get("rig"), str):
        return None
    return "metadata copy" if rec.metadata_source == "copy" else "metadata"


def run(args: argparse.Namespace) -> int:
    outputs = {"--accel-csv": args.accel_csv, "--estimates-csv": args.estimates_csv}
    refuse_overwrite({"FILE": args.file, "--rig": args.rig}, outputs)
    check_output_paths(outputs)  # every output writable, before any is written
    if args.host_filter is not None:
        if args.estimates_csv is None:
            raise InputError("adds columns to the estimates CSV: give --estimates-csv too",
                             field="--host-filter")
        try:  # an unknown name is refused before any work
            get_estimator(args.host_filter)
        except InputError as exc:
            raise InputError(exc.reason, field="--host-filter") from None
    # Counts, --verify and the CSV exports stream through the file in one pass with bounded
    # memory; --verify-firmware and --host-filter still read it whole.
    lazy = not args.verify_firmware and args.host_filter is None
    rec = JrecReader.open(args.file, lazy=lazy)
    try:
        _refuse_thin_stream(rec, args)
        return _run(rec, args, lazy)
    finally:
        rec.close()


def _refuse_thin_stream(rec: JrecReader, args: argparse.Namespace) -> None:
    """A recording made with --stream estimates or --every N > 1 (its metadata says so) holds
    no readings of every loop: nothing to verify or to run a host filter on. One line, exit 2."""
    stream = rec.metadata.get("stream") if isinstance(rec.metadata, dict) else None
    if not isinstance(stream, dict):
        return
    contents, every = stream.get("contents", "full"), stream.get("every", 1)
    if contents == "full" and every == 1:
        return
    how = f"--stream {contents}" + (f" --every {every}" if every != 1 else "")
    for option, wanted in (("--verify", args.verify), ("--verify-firmware", args.verify_firmware),
                           ("--host-filter", args.host_filter is not None)):
        if wanted:
            raise InputError(f"{option} needs the raw readings of every loop, and this "
                             f"recording was made with {how} (the board's estimates only)",
                             path=args.file, field=option)


def _one_pass(rec: JrecReader, args: argparse.Namespace) -> dict[str, Any]:
    """Counts, --verify and the CSV exports in one pass through a lazy reader: bounded memory
    for a recording of any length (the same figures and files as the whole-file path)."""
    sinks: list[Callable[[Frame], None]] = []
    verifier = None
    if args.verify:
        verifier = StreamVerifier(recording_rig(rec, "--verify"), rec.metadata)
        sinks.append(verifier.frame)
    exporter = None
    if args.accel_csv is not None or args.estimates_csv is not None:
        exporter = StreamExport(rec.path, rec.metadata, args.accel_csv, args.estimates_csv)
        sinks.append(exporter.frame)

    def each(fr: Frame) -> None:
        for sink in sinks:
            sink(fr)

    doc = summarize(rec, each if sinks else None)
    if verifier is not None:
        try:
            checked = verifier.result()
        except InputError as exc:
            raise InputError(exc.reason, path=rec.path, field=exc.field) from None
        if checked["verified_frames"] == 0:
            raise _no_start(rec, "--verify", "`mirror`")
        doc.update(checked)
    if exporter is not None:
        doc.update(exporter.write())
    return doc


def _run(rec: JrecReader, args: argparse.Namespace, lazy: bool) -> int:
    rig_source = _supply_rig(rec, args.rig)
    if lazy:
        doc = _one_pass(rec, args)
    else:
        doc = summarize(rec)
    doc["rig_source"] = rig_source
    if args.verify and not lazy:
        doc.update(verify(rec))
    if args.verify_firmware:
        doc.update(verify_firmware(rec))
    if not lazy:
        doc.update(_export(rec, args, doc))
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
        return 0
    lines = [
        f"{args.file}: {doc['frames']} frames over {doc['device_seconds']:.3f} s (device clock)",
        f"  lost (never arrived): {doc['frames_lost']}; {doc['duplicates']} duplicates, "
        f"{doc['out_of_order']} out of order, {doc['stale']} stale; "
        f"{doc['segments']} segment(s) (device restarts start new ones)",
        f"  damage: {doc['crc_errors']} CRC errors, {doc['malformed']} malformed, "
        f"{doc['oversize']} oversize, {doc['bytes_skipped']} bytes skipped",
    ]
    if doc["version_errors"] or doc["unknown_messages"]:
        others = ", ".join(f"version {v}: {n}" for v, n in doc["versions_seen"].items())
        lines.append(f"  skipped: {doc['version_errors']} frames of another protocol version "
                     f"({others}), {doc['unknown_messages']} of unknown message ids")
    for what in doc["file_damage"]:
        lines.append(f"  damaged file: {what}")
    if doc["file_damage"]:
        lines.append(f"  every intact record was read; rig from: {rig_source or 'nowhere'}")
    if doc["truncated_bytes"]:
        lines.append(f"  recording cut short: last {doc['truncated_bytes']} bytes incomplete "
                     "(every complete frame before the cut was read)")
    lines.append("  messages: " + ", ".join(f"{k} {v}" for k, v in doc["messages"].items()))
    for key in ("max_abs_dtheta_deg", "rms_dtheta_deg", "steady_max_abs_dtheta_deg",
                "steady_rms_dtheta_deg"):
        if doc.get(key) is not None:
            lines.append(f"  {key}: {doc[key]:.6f}")
    if "verified_frames" in doc:
        lines.append(f"  verified {doc['verified_frames']} frames in {doc['segments']} filter "
                     f"run(s); {doc['unverified_frames']} not verifiable")
    if "firmware_frames_compared" in doc:
        lines.append(f"  bit-exact against the x86 fixed-point core at "
                     f"{doc['firmware_rate_hz']} Hz: {doc['firmware_frames_compared']} frames "
                     f"in {doc['firmware_segments']} filter run(s), "
                     f"{doc['firmware_mismatches']} mismatching (theta "
                     f"{doc['firmware_mismatch_theta']}, omega_a "
                     f"{doc['firmware_mismatch_omega_a']}, omega_b "
                     f"{doc['firmware_mismatch_omega_b']}); "
                     f"{doc['firmware_unverified_frames']} not verifiable")
        if doc["firmware_first_mismatch"] is not None:
            lines.append(f"  first mismatch: {doc['firmware_first_mismatch']}")
    print("\n".join(lines))
    return 0
