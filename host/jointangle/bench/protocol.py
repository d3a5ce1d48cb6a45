"""`jointangle bench protocol`: the three host decoders timed on the same recorded log.

The log is what the board streams at full rate: a hello, then high-rate `sample_estimate` frames
(four sensors, realistic counts and estimates) with a `status` frame every 500. Timed, in one run:

- bulk:      `bulk.bulk_decode` of the whole log plus numpy columns of every frame (best of N);
- stream:    `framing.StreamDecoder` fed in 4 kB reads, every frame decoded to its dataclass;
- construct: per frame, COBS decode + `construct_defs.frame_body().parse` (CRC checked).

The slower decoders run on a prefix of the same log (their per-frame cost does not depend on the
log length); the frame counts used are reported. Before timing, the bulk and streaming decoders
are checked to agree on the log and on a corrupted copy. Wall-clock figures go to the JSON only,
never into test assertions.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.codec import decode_message, encode_message
from jointangle.protocol.construct_defs import frame_body, parse_chunks
from jointangle.protocol.framing import StreamDecoder, frame_summary

DEFAULT_FRAMES = 200_000


def _hello() -> msgs.Hello:
    inventory = tuple(msgs.HelloSensor(link=k // 2, model=msgs.SensorModel.ADXL345,
                                       mux_channel=k // 2, address=0x53 if k % 2 else 0x1D,
                                       chip_id=0xE5, range_g=2, status=0) for k in range(4))
    return msgs.Hello(protocol_version=msgs.PROTOCOL_VERSION, schema_hash=msgs.SCHEMA_HASH,
                      firmware_major=0, firmware_minor=1, firmware_patch=0,
                      build=b"bench".ljust(12, b"\x00"), board=msgs.Board.NATIVE,
                      sample_rate_hz=500, stream_mode=msgs.StreamMode.SAMPLE_ESTIMATE,
                      eeprom=msgs.EepromState.OK, sensors=inventory)


def synthetic_log(frames: int = DEFAULT_FRAMES, seed: int = 0) -> bytes:
    """A realistic 500 Hz stream: counts of ~1 g with noise, a swinging joint, status frames."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 500.0
    theta = 0.8 * np.sin(2 * np.pi * 0.2 * t)
    omega = 0.8 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t)
    counts = rng.normal(0.0, 40.0, size=(frames, 4, 3)).astype(np.int64)
    counts[:, :, 2] += 256  # gravity on z, ADXL345 full resolution
    counts[:, :, 0] += (200 * np.sin(theta))[:, None].astype(np.int64)
    out = [encode_message(_hello(), 0, 0)]
    seq = 1
    for i in range(frames):
        if i and i % 500 == 0:
            status = msgs.Status(uptime_ms=i * 2, loop_overruns=0, uart_drops=0, loop_rate_hz=500,
                                 idle_permille=300, eeprom=0, stream_mode=4, rx_errors=0,
                                 sensors=tuple(msgs.StatusSensor(0, 0, 0, 0, 0) for _ in range(4)))
            out.append(encode_message(status, seq, 2000 * i + 1000))
            seq += 1
        sensors = tuple(msgs.SampleEstimateSensor(x=int(c[0]), y=int(c[1]), z=int(c[2]), fresh=1,
                                                  status=0) for c in counts[i])
        msg = msgs.SampleEstimate(theta=int(theta[i] * 2**24), omega_a=int(omega[i] * 2**16),
                                  omega_b=0, health=1, sensors=sensors)
        out.append(encode_message(msg, seq & 0xFFFF, (2000 * i + 1500) & 0xFFFFFFFF))
        seq += 1
    return b"".join(out)


def corrupt(log: bytes, fraction: float = 1e-4, seed: int = 1) -> bytes:
    """Flip, drop and insert random bytes at `fraction` of the positions."""
    rng = np.random.default_rng(seed)
    buf = bytearray(log)
    for p in sorted(rng.integers(0, len(buf), int(len(buf) * fraction)).tolist(), reverse=True):
        op = int(rng.integers(0, 3))
        if op == 0:
            buf[p] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:
            del buf[p]
        else:
            buf.insert(p, int(rng.integers(0, 256)))
    return bytes(buf)


def _prefix(log: bytes, frames: int) -> bytes:
    """The first `frames` complete frames of a clean log."""
    end = -1
    for _ in range(frames):
        end = log.find(b"\x00", end + 1)
        if end < 0:
            return log
    return log[: end + 1]


def _bulk(log: bytes) -> int:
    res = bulk_decode(log)
    for name in ("hello", "sample_estimate", "status"):
        res.columns(name)
    return len(res)


def _stream(log: bytes) -> int:
    dec = StreamDecoder()
    n = 0
    for i in range(0, len(log), 4096):
        for fr in dec.feed(log[i : i + 4096]):
            decode_message(fr)
            n += 1
    return n


def _construct(log: bytes) -> int:
    return len(parse_chunks(log.split(b"\x00")[:-1], frame_body()))


def _rate(fn: Any, data: bytes, repeats: int) -> tuple[float, int]:
    best = float("inf")
    n = 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = fn(data)
        best = min(best, time.perf_counter() - t0)
    return n / best, n


def run_protocol_bench(frames: int = DEFAULT_FRAMES, *, stream_frames: int = 50_000,
                       construct_frames: int = 10_000, repeats: int = 5,
                       seed: int = 0) -> dict[str, Any]:
    """Time the three decoders on one synthetic log; returns the `bench protocol` JSON object."""
    log = synthetic_log(frames, seed)
    damaged = corrupt(log, seed=seed + 1)
    for data in (log, damaged):  # the bulk path must equal the streaming one before timing it
        ref = StreamDecoder()
        got = ref.feed(data)
        bulk = bulk_decode(data)
        if frame_summary(bulk.frames()) != frame_summary(got) or \
                bulk.stats.as_dict() != ref.stats.as_dict():
            raise RuntimeError("bulk and streaming decoders disagree")
    bulk_rate, bulk_n = _rate(_bulk, log, repeats)
    bulk_bad_rate, _ = _rate(_bulk, damaged, repeats)
    stream_rate, stream_n = _rate(_stream, _prefix(log, stream_frames), 1)
    cons_rate, cons_n = _rate(_construct, _prefix(log, construct_frames), 1)
    hello = encode_message(_hello(), 0, 0)
    return {
        "bulk_frames_per_s": round(bulk_rate),
        "stream_frames_per_s": round(stream_rate),
        "construct_frames_per_s": round(cons_rate),
        "frame_bytes": len(_prefix(log, 2)) - len(hello),  # the high-rate frame, 4 sensors
        "mean_frame_bytes": round(len(log) / bulk_n, 2) if bulk_n else 0.0,
        "bulk_over_construct": round(bulk_rate / cons_rate, 1),
        "bulk_corrupted_frames_per_s": round(bulk_bad_rate),
        "log_frames": bulk_n,
        "log_bytes": len(log),
        "stream_frames": stream_n,
        "construct_frames": cons_n,
        "corrupted_log_damage": bulk_decode(damaged).stats.as_dict(),
    }


def describe_protocol(doc: dict[str, Any]) -> str:
    """Human-readable summary of run_protocol_bench's result."""
    return "\n".join([
        f"log: {doc['log_frames']} frames, {doc['log_bytes']} bytes "
        f"(high-rate frame {doc['frame_bytes']} bytes)",
        f"bulk (numpy):      {doc['bulk_frames_per_s']:>12,} frames/s "
        f"({doc['bulk_over_construct']}x construct)",
        f"bulk, corrupted:   {doc['bulk_corrupted_frames_per_s']:>12,} frames/s",
        f"stream (python):   {doc['stream_frames_per_s']:>12,} frames/s",
        f"construct:         {doc['construct_frames_per_s']:>12,} frames/s",
    ])
