"""Bit-exact check of a board's estimates against the x86 build of the same fixed-point core.

`jointangle replay FILE.jrec --verify-firmware`: every `sample_estimate` frame carries the raw
counts the board read and the θ (Q24), ω_a, ω_b (Q16) it streamed. From each filter start
(health `reset`, the segments of `replay --verify`, `jointangle.device.verify.segments`) the counts
are calibrated exactly as the app does and run through `ja_filter_replay_fixed_raw_periods`
(firmware/platform/posix/filter_replay.cpp, the core compiled for x86); the three streamed
integers must be equal frame by frame.

The float32 steps are the app's own, in its order of operations (IEEE single on both machines;
avr-libc's and x86's +, −, ×, ÷ round to nearest alike):

- calibration map: `jointangle.device.calibration_map` (the app's `MakeCalibrationMap`).
- geometry (firmware/app/app.cpp `ConfigureFilter`): positions f32(µm)·1e-6f; with
  set_filter.accel_sigma = 0 (what `record` and `live` send) the noise variance per reading is
  σ·σ·(rate·0.5f) + lsb·lsb/12.0f with σ = (density_µg·1e-6f)·g; dt = 1.0f / f32(rate).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jointangle.device.calibration_map import (
    F32,
    STANDARD_GRAVITY_F32,
    DeviceMaps,
    from_micro,
    mps2_per_count,
)
from jointangle.device.rig import board_read_delays, filter_runs
from jointangle.device.verify import segments
from jointangle.errors import InputError
from jointangle.estimators.mirror import MAX_SENSORS_PER_LINK, slot_readings, step_periods
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig

DENSITY_UG = {"adxl345": 290.0, "adxl357": 80.0, "bno055": 150.0}  # app.cpp DensityUg
RAW_OUTPUTS_PER_STEP = 6  # filter_replay.cpp kRawOutputsPerStep


def chosen_per_link(rig: Rig, chosen: tuple[int, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The chosen sensor indices (rig order) split by link."""
    sensors = rig.all_sensors()
    a = tuple(i for i in chosen if sensors[i][0] == "a")
    b = tuple(i for i in chosen if sensors[i][0] == "b")
    return a, b


def device_geometry(rig: Rig, chosen: tuple[int, ...], rate_hz: int) -> np.ndarray:
    """The two ArrayGeometry the app configures (mirror.GEOMETRY_PER_LINK float32 per link, a
    then b: sensors in use, x, y per slot, joint x, y, noise variance per reading, read delay
    per slot; unused slots 0)."""
    sensors = rig.all_sensors()
    rate = F32(rate_hz)
    out: list[np.float32] = []
    for name, picked in zip(("a", "b"), chosen_per_link(rig, chosen), strict=True):
        out.append(F32(len(picked)))
        noise: list[np.float32] = []
        for idx in picked:
            _, _, s = sensors[idx]
            out += [from_micro(s.position[0]), from_micro(s.position[1])]
            sigma = F32(F32(F32(DENSITY_UG[s.model]) * F32(1e-6)) * STANDARD_GRAVITY_F32)
            lsb = mps2_per_count(s.model, s.range_g)
            var = F32(F32(F32(sigma * sigma) * F32(rate * F32(0.5)))
                      + F32(F32(lsb * lsb) / F32(12.0)))
            noise += [var, var]
        spare = MAX_SENSORS_PER_LINK - len(picked)
        out += [F32(0)] * (2 * spare)
        joint = rig.links[name].joint
        out += [from_micro(joint[0]), from_micro(joint[1])]
        out += noise + [F32(0)] * (2 * spare)
        # read delays as the app forms them: f32(hello's µs) · 1e-6f
        out += [from_micro(sensors[idx][2].read_delay_s) for idx in picked]
        out += [F32(0)] * spare
    return np.asarray(out, dtype=np.float32)


def run_fixed_core(library: Path, geometry: np.ndarray, rate_hz: int,
                   acc_q16: np.ndarray, periods: np.ndarray | None = None) -> np.ndarray:
    """`ja_filter_replay_fixed_raw_periods` on readings (T, 8) int32 and each step's sample
    periods (T,) (None = 1 each); (T, 6) int32 outputs."""
    lib = ctypes.CDLL(str(library))
    if not hasattr(lib, "ja_filter_replay_fixed_raw_periods"):
        raise InputError(f"{library} has no ja_filter_replay_fixed_raw_periods: rebuild the CMake "
                         "target ja_filter_replay", field="JOINTANGLE_FIRMWARE_LIB")
    if lib.ja_filter_raw_outputs_per_step() != RAW_OUTPUTS_PER_STEP:
        raise InputError(f"{library} has a different output layout: rebuild it",
                         field="JOINTANGLE_FIRMWARE_LIB")
    fn = lib.ja_filter_replay_fixed_raw_periods
    i32p = ctypes.POINTER(ctypes.c_int32)
    u8p = ctypes.POINTER(ctypes.c_uint8)
    fn.argtypes = [ctypes.POINTER(ctypes.c_float), ctypes.c_float, ctypes.c_int32, i32p, u8p,
                   i32p, ctypes.POINTER(ctypes.c_uint32)]
    fn.restype = ctypes.c_int
    geo = np.ascontiguousarray(geometry, dtype=np.float32)
    acc = np.ascontiguousarray(acc_q16, dtype=np.int32)
    T = int(acc.shape[0])
    out = np.zeros((T, RAW_OUTPUTS_PER_STEP), dtype=np.int32)
    stats = np.zeros(2, dtype=np.uint32)
    dt = F32(F32(1.0) / F32(rate_hz))
    per = None
    if periods is not None:
        if len(periods) != T:
            raise ValueError(f"periods has {len(periods)} entries for {T} steps")
        per = np.ascontiguousarray(periods, dtype=np.uint8)
    rc = fn(geo.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), float(dt), T,
            acc.ctypes.data_as(i32p), None if per is None else per.ctypes.data_as(u8p),
            out.ctypes.data_as(i32p),
            stats.ctypes.data_as(ctypes.POINTER(ctypes.c_uint32)))
    if rc != 0:
        raise InputError("the x86 core rejected the device geometry (firmware/core/FILTER.md)",
                         field="links")
    return out


@dataclass
class BitExactResult:
    frames_compared: int = 0
    mismatches: int = 0  # frames where θ, ω_a or ω_b differ
    mismatch_theta: int = 0
    mismatch_omega_a: int = 0
    mismatch_omega_b: int = 0
    segments: int = 0
    unverified_frames: int = 0
    first_mismatch: dict[str, Any] | None = None
    library: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "firmware_frames_compared": self.frames_compared,
            "firmware_mismatches": self.mismatches,
            "firmware_mismatch_theta": self.mismatch_theta,
            "firmware_mismatch_omega_a": self.mismatch_omega_a,
            "firmware_mismatch_omega_b": self.mismatch_omega_b,
            "firmware_segments": self.segments,
            "firmware_unverified_frames": self.unverified_frames,
            "firmware_first_mismatch": self.first_mismatch,
            "firmware_library": self.library,
        }


def compare_columns(rig: Rig, hello: msgs.Hello, rate_hz: int, cols: dict[str, np.ndarray],
                    lost_before: np.ndarray, library: Path) -> BitExactResult:
    """The board's streamed θ, ω_a, ω_b against the x86 fixed-point core, per filter run.

    rig: the rig the board was configured from (positions, models, calibration); hello: the
    board's (its inventory, checked against the rig, and its read delays); cols: the bulk
    decoder's sample_estimate columns; lost_before (T,): frames missing before each one.
    """
    rig = board_read_delays(rig, hello)
    maps = DeviceMaps.from_rig(rig)
    counts = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
    n = len(rig.all_sensors())
    if counts.shape[1] != n:
        raise InputError(f"frames carry {counts.shape[1]} sensors, the rig has {n}",
                         field="sample_estimate")
    res = BitExactResult(library=str(library))
    board = np.stack([cols["theta"], cols["omega_a"], cols["omega_b"]], axis=1).astype(np.int64)
    for seg in segments(cols["health"], cols["sensors.status"], lost_before, rig):
        if not filter_runs(rig, seg.chosen):
            continue
        a, b = chosen_per_link(rig, seg.chosen)
        q16 = maps.readings_q16(counts[seg.start:seg.stop])  # (T, n, 2)
        acc = slot_readings(q16[:, list(seg.chosen), :].reshape(q16.shape[0], -1), (len(a), len(b)))
        periods = step_periods(cols["t_us"][seg.start:seg.stop], rate_hz)
        out = run_fixed_core(library, device_geometry(rig, seg.chosen, rate_hz), rate_hz, acc,
                             periods)
        fw = board[seg.start:seg.stop]
        diff = fw != out[:, :3].astype(np.int64)
        bad = diff.any(axis=1)
        res.segments += 1
        res.frames_compared += int(fw.shape[0])
        res.mismatches += int(bad.sum())
        res.mismatch_theta += int(diff[:, 0].sum())
        res.mismatch_omega_a += int(diff[:, 1].sum())
        res.mismatch_omega_b += int(diff[:, 2].sum())
        if bad.any() and res.first_mismatch is None:
            k = int(np.argmax(bad))
            res.first_mismatch = {
                "frame": seg.start + k, "step": k,
                "board": [int(v) for v in fw[k]], "x86": [int(v) for v in out[k, :3]]}
    res.unverified_frames = int(counts.shape[0]) - res.frames_compared
    return res
