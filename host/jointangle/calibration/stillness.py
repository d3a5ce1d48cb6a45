"""Finding the still stretches of a recording, and each sensor's noise measured in them.

A sample is still when, over a centred window, every axis of every sensor varies no more than
its noise allows: windowed standard deviation ≤ factor × σ_floor, where σ_floor is the larger
of the rig's expected per-sample σ (noise density · g · √(fs/2), with LSB²/12 of quantisation)
and the quietest windows actually seen (a low percentile), so a sensor noisier than its
datasheet is not taken for one that never stops moving. Still runs shorter than `min_still_s`
are dropped and `trim_s` is cut from both ends. A run that passes the window test but whose
first and last thirds disagree by more than `drift_factor` standard errors (a slow creep the
short window cannot see) is kept but marked not still, with the reason.

Noise: the pooled standard deviation about each still run's mean, per sensor axis; the noise
density in µg/√Hz is σ / (g · 10⁻⁶ · √(fs/2)) after removing quantisation (σ² − LSB²/12), the
same convention as the rig file's `noise_density_ug` and the filters' Q̂ (docs/design.md §3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointangle.rig import Rig
from jointangle.sensors import STANDARD_GRAVITY


@dataclass(frozen=True)
class StillnessSettings:
    window_s: float = 0.5  # centred window of the standard-deviation test
    min_still_s: float = 1.0  # shortest still run kept (after trimming)
    trim_s: float = 0.2  # cut from both ends of a still run
    sigma_factor: float = 2.0  # still: windowed σ ≤ factor × σ_floor on every channel
    floor_percentile: float = 10.0  # the quietest windows' σ, when above the expected σ
    drift_factor: float = 6.0  # first vs last third: allowed difference in standard errors
    min_drift_mps2: float = 0.001 * STANDARD_GRAVITY  # ... and never flagged below 1 mg


DEFAULT_STILLNESS = StillnessSettings()


@dataclass(frozen=True)
class StillSegment:
    """One still run [start, stop) of samples and its per-sensor statistics."""

    start: int
    stop: int
    t_start: float  # s
    t_stop: float  # s
    mean: np.ndarray  # (n_sensors, 3) m/s²
    std: np.ndarray  # (n_sensors, 3) m/s²
    drift: np.ndarray  # (n_sensors, 3) m/s², mean of the last third − mean of the first
    reason: str | None = None  # why it is not usable as a pose (None: still)

    @property
    def still(self) -> bool:
        return self.reason is None

    @property
    def count(self) -> int:
        return self.stop - self.start


def expected_sigma(rig: Rig) -> np.ndarray:
    """Per-sample σ (n_sensors, 3) in m/s² the rig file predicts: density and quantisation."""
    out = []
    for _, _, s in rig.all_sensors():
        white = np.asarray(s.density_ug) * 1e-6 * STANDARD_GRAVITY * math.sqrt(
            rig.sample_rate_hz / 2.0)
        q2 = s.lsb_mps2() ** 2 / 12.0 if s.quantize else 0.0
        out.append(np.sqrt(white**2 + q2))
    return np.array(out)


def windowed_std(x: np.ndarray, window: int) -> np.ndarray:
    """Standard deviation over a centred window of `window` samples along axis 0 (edges use
    the nearest full window). Running sums of x and x² about the channel mean."""
    n = x.shape[0]
    w = max(2, min(window, n))
    xc = x - x.mean(axis=0)
    c1 = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(xc, axis=0)])
    c2 = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(xc * xc, axis=0)])
    starts = np.clip(np.arange(n) - w // 2, 0, n - w)
    s1 = c1[starts + w] - c1[starts]
    s2 = c2[starts + w] - c2[starts]
    var = np.maximum(s2 - s1 * s1 / w, 0.0) / (w - 1)
    return np.asarray(np.sqrt(var))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def creep_test(t: np.ndarray, r: np.ndarray, start: int, floor: np.ndarray,
               drift_factor: float, min_drift_mps2: float,
               verb: str = "drifted") -> StillSegment:
    """The hold r (m, n_sensors, 3) at times t, samples start.. of the recording, as a
    StillSegment; rejected (reason set) when the means of its first and last thirds differ by
    more than drift_factor standard errors of that difference (σ·√(2/third), σ floored at
    floor), and never by less than min_drift_mps2."""
    n = len(r)
    third = max(1, n // 3)
    drift = r[-third:].mean(axis=0) - r[:third].mean(axis=0)
    std = r.std(axis=0, ddof=1)
    # Standard error of a difference of two means of `third` samples each.
    se = np.maximum(std, floor) * math.sqrt(2.0 / third)
    limit = np.maximum(drift_factor * se, min_drift_mps2)
    reason = None
    if np.any(np.abs(drift) > limit):
        k, ax = np.unravel_index(int(np.argmax(np.abs(drift) / limit)), drift.shape)
        reason = (f"not still: sensor {k} axis {'xyz'[ax]} {verb} "
                  f"{abs(drift[k, ax]) / STANDARD_GRAVITY * 1e3:.1f} mg during the hold")
    return StillSegment(start, start + n, float(t[0]), float(t[-1]), r.mean(axis=0), std,
                        drift, reason)


def detect_still(rig: Rig, t: np.ndarray, readings: np.ndarray,
                 settings: StillnessSettings = DEFAULT_STILLNESS) -> list[StillSegment]:
    """Still segments of readings (T, n_sensors, 3), in time order (see the module doc)."""
    fs = rig.sample_rate_hz
    n = readings.shape[0]
    if n < 3:
        return []
    window = max(3, round(settings.window_s * fs))
    wstd = windowed_std(readings, window)  # (T, n, 3)
    floor = np.maximum(expected_sigma(rig), np.percentile(wstd, settings.floor_percentile,
                                                          axis=0))
    still = np.all(wstd <= settings.sigma_factor * floor, axis=(1, 2))
    trim = round(settings.trim_s * fs)
    min_len = max(3, round(settings.min_still_s * fs))
    out = []
    for a, b in _runs(still):
        a, b = a + trim, b - trim
        if b - a < min_len:
            continue
        out.append(creep_test(t[a:b], readings[a:b], a, floor, settings.drift_factor,
                              settings.min_drift_mps2))
    return out


@dataclass(frozen=True)
class NoiseEstimate:
    """Each sensor's noise measured while still."""

    sigma_mps2: np.ndarray  # (n_sensors, 3) per-sample σ, quantisation included
    density_ug: np.ndarray  # (n_sensors, 3) µg/√Hz, quantisation removed
    samples: int


def measure_noise(rig: Rig, readings: np.ndarray, segments: list[StillSegment]
                  ) -> NoiseEstimate | None:
    """Pooled σ about each still segment's mean, and the equivalent noise density."""
    good = [s for s in segments if s.still]
    if not good:
        return None
    ss = sum(((readings[s.start:s.stop] - s.mean) ** 2).sum(axis=0) for s in good)
    dof = sum(s.count - 1 for s in good)
    sigma = np.sqrt(ss / dof)
    q2 = np.array([[s.lsb_mps2() ** 2 / 12.0 if s.quantize else 0.0] * 3
                   for _, _, s in rig.all_sensors()])
    white = np.sqrt(np.maximum(sigma**2 - q2, 0.0))
    density = white / (STANDARD_GRAVITY * 1e-6 * math.sqrt(rig.sample_rate_hz / 2.0))
    return NoiseEstimate(sigma_mps2=sigma, density_ug=density, samples=dof + len(good))
