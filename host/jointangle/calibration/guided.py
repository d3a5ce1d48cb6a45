"""The guided calibration flow: which pose next, a live "hold still" indicator, each pose checked
as it is taken, then the fit (pipeline.calibrate_segments) over the poses collected.

`PoseCollector` is fed the stream of raw readings (sensor frames, m/s²) as it arrives and walks
through the expected poses (`sim.static_poses.guided_sequence`: the paper's seven holds):

1. "hold": wait until the readings are still — over the last `window_s`, every channel's standard
   deviation ≤ `sigma_factor` × its expected σ (datasheet density · g · √(fs/2), quantisation
   LSB²/12, never below `min_sigma_mps2`), no sensor fault bit set — and stay still for `hold_s`.
   The indicator shows the still time against hold_s; any movement starts it again.
2. The hold (the last hold_s of the still run) is checked: its first and last thirds must agree
   (a creep the window cannot see: the same test as `stillness.detect_still`; while a move is
   still settling the flow waits up to settle_s for that), and each link's measured "up" must
   lie along the pose's link axis (`pipeline.identify_poses`, within snap_tolerance_deg). A hold
   that fails is rejected with the reason and the same pose is asked for again.
   A pose of the fixture-free method ("any") must instead be new: each link's "up" at least
   `new_pose_deg` from every pose taken so far.
3. "move": before the next hold is accepted the rig must be seen moving (a window that is not
   still, or its direction more than `moved_deg` away from the last hold), so one long hold
   is never taken for two poses.
The result is a list of still segments over the collected samples, which `calibrate()` hands to
the same fit, grading and rejection rules as the offline `jointangle calibrate --poses`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from jointangle.calibration.pipeline import (
    DEFAULT_QUALITY,
    CalibrationReport,
    QualitySettings,
    calibrate_segments,
    identify_poses,
)
from jointangle.calibration.stillness import StillSegment, creep_test, expected_sigma
from jointangle.rig import LINK_NAMES, Rig
from jointangle.sensors import STANDARD_GRAVITY

ANY = "any"  # a pose of the fixture-free method: any new still orientation

POSE_INSTRUCTIONS = {
    ANY: "hold the rig still in a NEW orientation — tilted, turned over, the joint at any "
         "angle — at least 20° from every pose taken so far",
    "+z": "lay the rig straight and flat on the bench, its top (+z) facing up",
    "-z": "turn the straight rig over: flat on the bench, its top (+z) facing down",
    "+x": "stand the straight rig on end, the links' +x axis pointing straight up",
    "-x": "stand the straight rig on its other end, the links' +x axis pointing down",
    "+y": "stand the straight rig on its edge, the links' +y axis pointing up",
    "-y": "stand the straight rig on its other edge, the links' +y axis pointing down",
}


@dataclass(frozen=True)
class GuidedSettings:
    hold_s: float = 2.0  # still this long to take a pose
    window_s: float = 0.5  # window of the stillness test
    sigma_factor: float = 3.0  # still: windowed σ ≤ factor × expected σ, every channel
    min_sigma_mps2: float = 0.001 * STANDARD_GRAVITY  # expected σ never taken below 1 mg
    drift_factor: float = 6.0  # first vs last third of a hold, in standard errors
    min_drift_mps2: float = 0.001 * STANDARD_GRAVITY  # ... never flagged below 1 mg
    moved_deg: float = 10.0  # this far from the last hold counts as moved
    settle_s: float = 1.5  # a still run that creeps may settle this long before rejection
    new_pose_deg: float = 20.0  # an "any" pose: each link this far from every pose taken


DEFAULT_GUIDED = GuidedSettings()


@dataclass(frozen=True)
class PoseAttempt:
    """One hold taken: accepted as pose `label` or rejected with the reason."""

    label: str
    t_start: float
    t_stop: float
    reason: str | None
    axes: dict[str, str | None]  # link -> the axis it was found along

    @property
    def accepted(self) -> bool:
        return self.reason is None


@dataclass
class FlowState:
    """What the user sees."""

    index: int  # pose being asked for (== len(labels): done)
    total: int
    label: str | None
    phase: str  # "move" (go to the pose), "hold" (hold still), "done"
    still_s: float
    hold_s: float
    message: str | None = None
    attempts: list[PoseAttempt] = field(default_factory=list)

    @property
    def instruction(self) -> str:
        return "" if self.label is None else POSE_INSTRUCTIONS.get(self.label, self.label)

    @property
    def rejected(self) -> list[PoseAttempt]:
        return [a for a in self.attempts if not a.accepted]


class PoseCollector:
    """Walks through `labels` as readings arrive (see the module doc)."""

    def __init__(self, rig: Rig, labels: Sequence[str],
                 settings: GuidedSettings = DEFAULT_GUIDED,
                 quality: QualitySettings = DEFAULT_QUALITY) -> None:
        unknown = [lb for lb in labels if lb not in POSE_INSTRUCTIONS]
        if unknown:
            raise ValueError(f"unknown poses {unknown}")
        self.rig = rig
        self.labels = list(labels)
        self.settings = settings
        self.quality = quality
        fs = rig.sample_rate_hz
        self._n_window = max(3, round(settings.window_s * fs))
        self._n_hold = max(self._n_window, round(settings.hold_s * fs))
        self._n_settle = round(settings.settle_s * fs)
        self._limit = settings.sigma_factor * np.maximum(expected_sigma(rig),
                                                         settings.min_sigma_mps2)
        self._n = len(rig.all_sensors())
        self._t: list[float] = []
        self._r: list[np.ndarray] = []
        self._run_start: int | None = None  # first still sample of the current run
        self._need_motion = False
        self._last_up: np.ndarray | None = None  # (n, 3) mean of the last hold taken
        self._kept_t: list[np.ndarray] = []
        self._kept_r: list[np.ndarray] = []
        self._kept_labels: list[str] = []
        self.segments: list[StillSegment] = []
        self._ups: list[dict[str, np.ndarray]] = []  # each accepted hold's "up" per link
        self.state = FlowState(0, len(self.labels), self.labels[0] if self.labels else None,
                               "hold" if self.labels else "done", 0.0, settings.hold_s)

    @property
    def done(self) -> bool:
        return self.state.index >= len(self.labels)

    def feed(self, t: np.ndarray, readings: np.ndarray,
             faulty: Sequence[str] = ()) -> list[PoseAttempt]:
        """New samples: times (k,) s and readings (k, n, 3) m/s²; `faulty` names sensors with a
        fault bit in these samples. Returns the holds taken (accepted or rejected) meanwhile."""
        out: list[PoseAttempt] = []
        if self.done or len(t) == 0:
            return out
        if readings.shape[1:] != (self._n, 3):
            raise ValueError(f"readings of {readings.shape[1]} sensors, the rig has {self._n}")
        step = max(1, self._n_window // 2)
        if len(t) > step:  # every sample must fall inside some tested window
            for i in range(0, len(t), step):
                out += self.feed(t[i:i + step], readings[i:i + step], faulty)
            return out
        self._t.extend(float(x) for x in t)
        self._r.extend(np.asarray(readings, dtype=float))
        if faulty:
            self._run_start = None
            self.state.still_s = 0.0
            self.state.message = f"sensor fault ({', '.join(faulty)}): not taking this hold"
            self._trim()
            return out
        w = self._n_window
        if len(self._r) < w:
            return out
        win = np.asarray(self._r[-w:])
        still = bool(np.all(win.std(axis=0, ddof=1) <= self._limit))
        if self._need_motion:
            moved = not still
            if still and self._last_up is not None:
                cos = np.sum(_unit(win.mean(axis=0)) * self._last_up, axis=1)
                moved = bool(np.degrees(np.arccos(np.clip(cos.min(), -1, 1)))
                             > self.settings.moved_deg)
            if not moved:
                self.state.phase = "move"
                self._trim()
                return out
            self._need_motion = False
            self._run_start = None
        self.state.phase = "hold"
        if not still:
            self._run_start = None
            self.state.still_s = 0.0
            self._trim()
            return out
        if self._run_start is None:
            self._run_start = len(self._r) - w
        run = len(self._r) - self._run_start
        self.state.still_s = run / self.rig.sample_rate_hz
        if run >= self._n_hold:
            # The last hold_s seconds; while they still creep (a move settling), wait up to
            # settle_s longer before rejecting the hold.
            a = len(self._r) - self._n_hold
            seg = self._segment(a, len(self._r))
            if seg.reason is None or run >= self._n_hold + self._n_settle:
                out.append(self._take(seg, a, len(self._r)))
            else:
                self.state.message = "settling…"
        self._trim()
        return out

    def _segment(self, a: int, b: int) -> StillSegment:
        offset = sum(len(x) for x in self._kept_r)
        return _segment(np.asarray(self._t[a:b]), np.asarray(self._r[a:b]), offset,
                        self._limit / self.settings.sigma_factor, self.settings)

    def _trim(self) -> None:
        """Keep only what a hold in progress (or the next window) can still use."""
        keep = self._n_hold + 2 * self._n_window
        start = self._run_start if self._run_start is not None else len(self._r) - keep
        cut = max(0, min(start, len(self._r) - keep))
        if cut > 0:
            del self._t[:cut]
            del self._r[:cut]
            if self._run_start is not None:
                self._run_start -= cut

    def _take(self, seg: StillSegment, a: int, b: int) -> PoseAttempt:
        label = self.labels[self.state.index]
        seg_r = np.asarray(self._r[a:b])
        seg_t = np.asarray(self._t[a:b])
        axes: dict[str, str | None] = {}
        reason = seg.reason
        if reason is None:
            info = identify_poses(self.rig, [seg], self.quality)[0]
            axes = dict(info.axis)
            reason = info.reason
            wrong = [ln for ln in LINK_NAMES if info.axis[ln] != label]
            if label == ANY:
                wrong = []
                reason = reason or self._too_close(info.up)
            if reason is None and wrong:
                ln = wrong[0]
                found = info.axis[ln]
                reason = (f"link {ln} has {found or 'no axis'} up"
                          f" ({info.axis_error_deg[ln]:.0f}° from the nearest axis)"
                          if found is None else f"link {ln} has its {found} axis up")
                reason += f", pose {label} needs {label} up: {POSE_INSTRUCTIONS[label]}"
        attempt = PoseAttempt(label, float(seg_t[0]), float(seg_t[-1]), reason, axes)
        self.state.attempts.append(attempt)
        self._last_up = _unit(seg_r.mean(axis=0))
        # A hold in the wrong orientation is retaken only after a move; a creeping one at once.
        self._need_motion = seg.reason is None
        self._run_start = None
        self.state.still_s = 0.0
        self.state.phase = "move"
        if reason is None:
            self._ups.append(identify_poses(self.rig, [seg], self.quality)[0].up)
            self._kept_t.append(seg_t)
            self._kept_r.append(seg_r)
            self._kept_labels.append(label)
            self.segments.append(seg)
            self.state.index += 1
            self.state.message = f"pose {label} taken"
            if self.done:
                self.state.phase = "done"
                self.state.label = None
            else:
                self.state.label = self.labels[self.state.index]
        else:
            self.state.message = f"pose {label} rejected: {reason}"
        return attempt

    def _too_close(self, up: dict[str, np.ndarray]) -> str | None:
        """Why an "any" pose is not new: a link within new_pose_deg of a pose already taken."""
        for k, prev in enumerate(self._ups):
            for ln in LINK_NAMES:
                ang = float(np.degrees(np.arccos(np.clip(up[ln] @ prev[ln], -1.0, 1.0))))
                if ang < self.settings.new_pose_deg:
                    return (f"link {ln} is only {ang:.0f}° from pose {k + 1}: turn the rig to an "
                            f"orientation ≥ {self.settings.new_pose_deg:g}° from every pose "
                            "so far")
        return None

    def holds(self, labels: Sequence[str]) -> list[np.ndarray]:
        """The samples (T, n, 3) of each accepted hold of these poses, in the order taken."""
        return [r for lb, r in zip(self._kept_labels, self._kept_r, strict=True)
                if lb in labels]

    def readings(self) -> np.ndarray:
        """Every accepted hold's samples (T, n, 3), in the order taken (segments index it)."""
        if not self._kept_r:
            return np.zeros((0, self._n, 3))
        return np.concatenate(self._kept_r, axis=0)

    def calibrate(self, gravity_mps2: float = STANDARD_GRAVITY, method: str = "poses",
                  alignment: str = "link-poses") -> CalibrationReport:
        """The fit over the accepted holds, graded per sensor: "poses" (the paper's Appendix
        IV) or "gravity" (Madgwick §6.2: magnitude fit, then alignment)."""
        return calibrate_segments(self.rig, self.segments, self.readings(), method, alignment,
                                  gravity_mps2=gravity_mps2, quality=self.quality)


def _unit(v: np.ndarray) -> np.ndarray:
    return np.asarray(v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12))


def _segment(t: np.ndarray, r: np.ndarray, offset: int, floor: np.ndarray,
             s: GuidedSettings) -> StillSegment:
    """A hold as a StillSegment (indices into the collected samples), with the creep test of
    stillness.detect_still."""
    return creep_test(t, r, offset, floor, s.drift_factor, s.min_drift_mps2, "crept")
