"""The board's estimates checked against the host's float `mirror` of its filter.

`replay --verify` and `live` compare every firmware estimate with `mirror` (docs/design.md §3,
§5). For that comparison to mean anything, `mirror` must see the *same quantised inputs* the
firmware filtered, and start where the firmware's filter started:

- Inputs: the firmware's own Q15.16 readings (`calibration_map.device_readings`).
- Noise model and rate: the rig as the firmware sees it (`rig.device_rig`).
- Start: the firmware's filter runs from boot; a stream shows its (re)starts as health `reset`.
  `mirror` is run per *segment*: from a `reset` frame, as long as the filter is `running`, no
  frame is missing (a sequence gap means steps the host never saw), the stream did not start
  again (below) and the sensor choice stays.
- A stream start ends the segment. The firmware filters every loop whether it streams or not,
  and its sequence counter counts only the frames it sends: between a stream's end (a pulled
  cable, stop_stream) and the next start_stream it steps unseen *without* a sequence gap. After
  a reconnect, the frames it streams between the start_stream ack and the restart_filter the
  host sends next carry seq numbers right after the last frame before the cut, and followed as
  that run's continuation they differed by tens of degrees. `unseen_before` counts both: the
  frames lost and the stream starts (acks of start_stream) since the previous sample frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from jointangle.device.calibration_map import DeviceMaps, device_readings
from jointangle.device.rig import device_rig, filter_choice, filter_runs, sub_rig
from jointangle.errors import InputError
from jointangle.estimators.base import wrap
from jointangle.estimators.mirror import (
    MirrorSettings,
    MirrorState,
    output_theta,
    quantise_inputs,
    run_mirror,
    step_periods,
)
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig

THETA_LSB = 2.0**-24  # rad (sample_estimate.theta, Q24)
OMEGA_LSB = 2.0**-16  # rad/s (Q16)
STEADY_AFTER_S = 2.0  # docs/design.md §5: the tight parity bounds hold from 2 s after a start


def starts_stream(command_id: int | np.ndarray, error: int | np.ndarray) -> bool | np.ndarray:
    """Whether acks (command_id, error: an ack's fields, or the bulk decoder's ack columns) say
    the stream (re)started: start_stream accepted. A bool, or a bool array."""
    return (command_id == msgs.StartStream.MSG_ID) & (error == msgs.ErrorCode.OK)


def unseen_before(seq: np.ndarray, stream_start: np.ndarray, sample_index: np.ndarray
                  ) -> np.ndarray:
    """Per sample frame: nonzero where the host may have missed filter steps just before it
    (`segments`' lost_before) -- the frames lost (sequence gaps) plus the stream starts since
    the previous sample frame.

    seq (F,), stream_start (F,) bool: every delivered frame in order (stream_start: an ack that
    `starts_stream`); sample_index (T,): the sample frames' positions among them."""
    seq = np.asarray(seq, dtype=np.int64)
    gaps = np.zeros(seq.size, dtype=np.int64)
    gaps[1:] = (seq[1:] - seq[:-1] - 1) & 0xFFFF
    total = np.cumsum(gaps + np.asarray(stream_start, dtype=np.int64))
    idx = np.asarray(sample_index, dtype=np.int64)
    out = np.zeros(idx.size, dtype=np.int64)
    out[1:] = total[idx[1:]] - total[idx[:-1]]
    return out


def mirror_theta(rig: Rig, maps: DeviceMaps, counts: np.ndarray,
                 chosen: tuple[int, ...], state: MirrorState | None = None,
                 periods: np.ndarray | None = None) -> np.ndarray:
    """`mirror`'s θ (rad) for one segment of counts (T, n, 3) on the chosen sensors; with
    `state` (MirrorState.fresh(1) at the segment's start) the segment goes on from where the
    last call with that state stopped. periods (T,): each step's sample periods
    (`mirror.step_periods` of the frames' t_us); None = 1 each."""
    readings = device_readings(maps, counts)
    cols = [c for i in chosen for c in (2 * i, 2 * i + 1)]
    cfg = MirrorSettings.from_rig(sub_rig(rig, chosen))
    xs, _ = run_mirror(cfg, quantise_inputs(readings[:, cols][None]), state=state,
                       periods=periods)
    return output_theta(cfg, xs).reshape(-1)


@dataclass(frozen=True)
class Segment:
    start: int  # index into the sample_estimate columns
    stop: int
    chosen: tuple[int, ...]


def segments(health: np.ndarray, status: np.ndarray, lost_before: np.ndarray,
             rig: Rig) -> list[Segment]:
    """Runs of sample_estimate frames one `mirror` run can follow (see the module docstring).

    health (T,), status (T, n) per frame; lost_before (T,): nonzero where steps may be missing
    just before the frame (`unseen_before`: frames lost, or the stream started again). A segment
    starts at a frame with health `reset` and `running`.
    """
    out: list[Segment] = []
    start: int | None = None
    chosen: tuple[int, ...] = ()
    T = int(health.shape[0])
    for k in range(T):
        h = int(health[k])
        running = bool(h & msgs.FilterHealth.RUNNING)
        if start is not None:
            now = filter_choice(rig, status[k])
            if (not running or h & msgs.FilterHealth.RESET or lost_before[k] or now != chosen):
                out.append(Segment(start, k, chosen))
                start = None
        if start is None and running and h & msgs.FilterHealth.RESET:
            start, chosen = k, filter_choice(rig, status[k])
    if start is not None:
        out.append(Segment(start, T, chosen))
    return out


@dataclass
class VerifyResult:
    dtheta_deg: np.ndarray  # firmware − mirror, over every verified frame
    steady_dtheta_deg: np.ndarray  # the part from STEADY_AFTER_S after each start
    verified_frames: int
    unverified_frames: int
    segments: int

    def as_dict(self) -> dict[str, Any]:
        d, s = self.dtheta_deg, self.steady_dtheta_deg
        return {
            "max_abs_dtheta_deg": float(np.max(np.abs(d))) if d.size else None,
            "rms_dtheta_deg": float(np.sqrt(np.mean(d**2))) if d.size else None,
            "steady_max_abs_dtheta_deg": float(np.max(np.abs(s))) if s.size else None,
            "steady_rms_dtheta_deg": float(np.sqrt(np.mean(s**2))) if s.size else None,
            "verified_frames": self.verified_frames,
            "unverified_frames": self.unverified_frames,
            "segments": self.segments,
        }


def verify_columns(rig: Rig, hello: msgs.Hello, cols: dict[str, np.ndarray],
                   lost_before: np.ndarray) -> VerifyResult:
    """Firmware θ against `mirror` on sample_estimate columns (bulk decoder layout)."""
    drig = device_rig(rig, hello)
    maps = DeviceMaps.from_rig(drig)
    counts = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
    if counts.shape[1] != len(hello.sensors):
        raise InputError(f"frames carry {counts.shape[1]} sensors, the hello lists "
                         f"{len(hello.sensors)}", field="sample_estimate")
    segs = segments(cols["health"], cols["sensors.status"], lost_before, drig)
    steady_k = round(STEADY_AFTER_S * drig.sample_rate_hz)
    ds, steady = [], []
    verified = 0
    for seg in segs:
        if not filter_runs(drig, seg.chosen):
            continue
        periods = step_periods(cols["t_us"][seg.start:seg.stop], drig.sample_rate_hz)
        host = mirror_theta(drig, maps, counts[seg.start:seg.stop], seg.chosen, periods=periods)
        fw = cols["theta"][seg.start:seg.stop].astype(float) * THETA_LSB
        d = np.degrees(wrap(fw - host))
        ds.append(d)
        # Steady from STEADY_AFTER_S of the run's time: periods, not frames (an overrunning
        # board steps over several periods a frame).
        steady.append(d[np.cumsum(periods) - 1 >= steady_k])
        verified += d.size
    cat = np.concatenate(ds) if ds else np.zeros(0)
    st = np.concatenate(steady) if steady else np.zeros(0)
    return VerifyResult(cat, st, verified, int(counts.shape[0]) - verified, len(ds))
