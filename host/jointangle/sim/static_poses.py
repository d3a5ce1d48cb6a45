"""Static-pose recordings for calibration: a rig held still in a sequence of orientations.

A pose fixes, for each link, the direction of the specific force at rest ("up", since f = a − g
= −g when still) in that link's frame. Both links hang on one hinge whose axis is the links' z,
so link b's "up" is link a's turned about z by the joint angle: vᵃ = R(θ_ab) vᵇ (docs/design.md §3).
Between holds the rig is carried to the next pose: the direction follows a minimum-jerk slerp
and a handling bump is added so that two holds in the same orientation stay separate. The
transitions are not a dynamic model (no centripetal terms); calibration never uses them.

`with_sensor_errors` draws the unknown per-sensor errors a calibration has to find (issue 7:
misalignment ≤ 3°, scale ≤ 5 %, cross-axis and offsets ≤ 100 mg) into the rig's simulation
fields; `sim.sensor_model.sensor_distortion` gives the injected (M, b) back for grading.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from jointangle.rig import LINK_NAMES, LinkConfig, Rig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.sensor_model import sensor_reading

Vec3 = tuple[float, float, float]

MAX_MISALIGNMENT_DEG = 3.0
MAX_SCALE_ERROR = 0.05
MAX_CROSS_AXIS = 0.10  # 100 mg of cross-axis reading per g
MAX_OFFSET_MPS2 = 0.1 * STANDARD_GRAVITY  # 100 mg


@dataclass(frozen=True)
class StaticPose:
    """One held orientation: unit "up" vectors in link a's and link b's frames."""

    up_a: Vec3
    up_b: Vec3
    label: str = ""

    def up(self, link: str) -> np.ndarray:
        return np.asarray(self.up_a if link == "a" else self.up_b, dtype=float)


def _hinged(up_a: np.ndarray, theta_ab: float) -> Vec3:
    """Link b's components of a vector with link a components up_a: vᵇ = R(θ_ab)ᵀ vᵃ."""
    c, s = np.cos(theta_ab), np.sin(theta_ab)
    x, y, z = up_a
    return (float(c * x - s * y), float(s * x + c * y), float(z))


def pose(up_a: Sequence[float] | np.ndarray, theta_ab_deg: float = 0.0,
         label: str = "") -> StaticPose:
    """A pose from link a's "up" direction and the joint angle (0 = the rig held straight)."""
    u = np.asarray(up_a, dtype=float)
    u = u / np.linalg.norm(u)
    return StaticPose((float(u[0]), float(u[1]), float(u[2])),
                      _hinged(u, float(np.radians(theta_ab_deg))), label)


AXIS_LABELS = ("+x", "-x", "+y", "-y", "+z", "-z")
AXES: dict[str, Vec3] = {
    "+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0), "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0), "+z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
}


def axis_poses() -> list[StaticPose]:
    """The paper's calibration set (§V, Fig. 8b; Appendix IV): the straight rig with its link
    axes along ±g, starting and ending flat on the bench (+z up) — seven holds, six distinct."""
    order = ("+z", "+x", "-x", "+y", "-y", "-z", "+z")
    return [pose(AXES[k], 0.0, k) for k in order]


def random_poses(n: int, rng: np.random.Generator, max_hinge_deg: float = 90.0,
                 min_axis_distance_deg: float = 0.0) -> list[StaticPose]:
    """n orientations uniform on the sphere, each with a random joint angle within ±max;
    with min_axis_distance_deg, link a's "up" keeps at least that far from every link axis."""
    out: list[StaticPose] = []
    cos_min = np.cos(np.radians(min_axis_distance_deg))
    while len(out) < n:
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        hinge = float(rng.uniform(-max_hinge_deg, max_hinge_deg))
        p = pose(u, hinge, f"r{len(out)}")
        if min_axis_distance_deg > 0 and max(np.max(np.abs(p.up(ln)))
                                             for ln in LINK_NAMES) > cos_min:
            continue
        out.append(p)
    return out


@dataclass(frozen=True)
class PoseRecording:
    """A simulated calibration recording and its ground truth."""

    rig: Rig
    t: np.ndarray  # (T,) s
    readings: np.ndarray  # (T, n_sensors, 3) m/s², sensor frames, rig order
    f_link: np.ndarray  # (T, n_sensors, 3) true specific force, link frames
    poses: tuple[StaticPose, ...]
    holds: tuple[tuple[float, float], ...]  # (start, stop) s of each pose's hold


def _slerp(u0: np.ndarray, u1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Unit vectors between u0 and u1 at fractions s (K,) along the great circle."""
    cos = float(np.clip(u0 @ u1, -1.0, 1.0))
    ang = np.arccos(cos)
    if ang < 1e-9:
        return np.broadcast_to(u0, (len(s), 3)).copy()
    if np.pi - ang < 1e-6:  # antipodal: go round through any perpendicular direction
        perp = np.cross(u0, [1.0, 0.0, 0.0] if abs(u0[0]) < 0.9 else [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        return (np.cos(np.pi * s)[:, None] * u0 + np.sin(np.pi * s)[:, None] * perp)
    w0 = np.sin((1 - s) * ang) / np.sin(ang)
    w1 = np.sin(s * ang) / np.sin(ang)
    return w0[:, None] * u0 + w1[:, None] * u1


def _preroll(first: StaticPose, n: int, fs: float, gravity_mps2: float
             ) -> dict[str, np.ndarray]:
    """n samples of the rig being handled before the first hold: its "up" wobbles about the
    first pose (±0.5 rad-ish at ~1 Hz, two incommensurate frequencies) and settles into it as the
    wobble's amplitude falls linearly to zero."""
    t = np.arange(n) / fs
    fade = (1.0 - np.arange(n) / n)[:, None]
    wob = np.stack([np.sin(2 * np.pi * 1.3 * t), np.cos(2 * np.pi * 0.9 * t),
                    0.5 * np.sin(2 * np.pi * 0.7 * t)], axis=1)
    out = {}
    for ln in LINK_NAMES:
        u = first.up(ln)[None, :] + 0.5 * fade * wob
        out[ln] = gravity_mps2 * u / np.linalg.norm(u, axis=1, keepdims=True)
    return out


def static_pose_recording(rig: Rig, poses: Sequence[StaticPose], seed: int,
                          hold_s: float = 4.0, move_s: float = 1.5,
                          gravity_mps2: float = STANDARD_GRAVITY,
                          bump_mps2: float = 2.0, preroll_s: float = 0.0) -> PoseRecording:
    """Readings of every sensor of `rig` held in each pose for hold_s, carried between poses
    over move_s (minimum-jerk slerp plus a handling bump of bump_mps2 peak); with preroll_s, the
    rig is first handled (moving, never still) for that long before settling into the first
    pose (a virtual board plays that while the host connects)."""
    if not poses:
        raise ValueError("no poses")
    fs = rig.sample_rate_hz
    n_hold = max(1, round(hold_s * fs))
    n_move = max(1, round(move_s * fs))
    bump_rng = np.random.default_rng([seed, 7])
    per_link: dict[str, list[np.ndarray]] = {ln: [] for ln in LINK_NAMES}
    holds = []
    n = 0
    if preroll_s > 0:
        n_pre = round(preroll_s * fs)
        for ln, f in _preroll(poses[0], n_pre, fs, gravity_mps2).items():
            per_link[ln].append(f)
        n += n_pre
    for k, p in enumerate(poses):
        if k > 0:
            tau = (np.arange(n_move) + 1) / (n_move + 1)
            s = tau**3 * (10 - 15 * tau + 6 * tau**2)
            bump_dir = bump_rng.standard_normal(3)
            bump_dir /= np.linalg.norm(bump_dir)
            for ln in LINK_NAMES:
                up = _slerp(poses[k - 1].up(ln), p.up(ln), s)
                bump = bump_mps2 * np.sin(np.pi * tau)[:, None] ** 2 * bump_dir
                per_link[ln].append(gravity_mps2 * up + bump)
            n += n_move
        holds.append((n / fs, (n + n_hold) / fs))
        for ln in LINK_NAMES:
            per_link[ln].append(np.broadcast_to(gravity_mps2 * p.up(ln), (n_hold, 3)))
        n += n_hold
    rng = np.random.default_rng(seed)
    f_cols = []
    cols = []
    for ln in LINK_NAMES:
        f = np.concatenate(per_link[ln], axis=0)
        for sensor in rig.links[ln].sensors:
            f_cols.append(f)
            cols.append(sensor_reading(sensor, f, fs, rng))
    return PoseRecording(rig=rig, t=np.arange(n) / fs, readings=np.stack(cols, axis=1),
                         f_link=np.stack(f_cols, axis=1), poses=tuple(poses),
                         holds=tuple(holds))


GUIDED_ANY_POSES = 10  # fixture-free method: arbitrary orientations after the two link poses


def guided_sequence(method: str = "poses") -> list[str]:
    """The poses `jointangle calibrate --port` asks for, in order. "poses": the paper's set
    (`axis_poses`); "gravity" (fixture-free): flat on the bench and link pointing up (for the
    alignment), then GUIDED_ANY_POSES new orientations ("any")."""
    if method == "gravity":
        return ["+z", "+x"] + ["any"] * GUIDED_ANY_POSES
    return [p.label for p in axis_poses()]


def spread_poses(n: int, seed: int, min_apart_deg: float = 35.0) -> list[StaticPose]:
    """n random orientations (random joint angles within ±90°), each link's "up" at least
    min_apart_deg from the other poses' and 25° from every link axis."""
    rng = np.random.default_rng([seed, 13])
    out: list[StaticPose] = []
    cos_apart = np.cos(np.radians(min_apart_deg))
    while len(out) < n:
        cand = random_poses(1, rng, min_axis_distance_deg=25.0)[0]
        if all(float(cand.up(ln) @ p.up(ln)) < cos_apart for p in out for ln in LINK_NAMES):
            out.append(replace(cand, label=f"any{len(out)}"))
    return out


def guided_motion_poses(labels: Sequence[str], mistake_at: int | None = None,
                        seed: int = 0) -> list[StaticPose]:
    """What a virtual board plays for the guided flow: each pose of `labels` in order (axis
    labels: the straight rig; "any": `spread_poses`). With mistake_at = k, the rig is first
    held in a wrong pose where pose k is expected — a quarter turn away from an axis pose, or,
    for "any", the previous pose again — which the flow must reject before pose k."""
    anys = iter(spread_poses(sum(lb == "any" for lb in labels), seed))
    out: list[StaticPose] = []
    for k, label in enumerate(labels):
        p = next(anys) if label == "any" else pose(AXES[label], 0.0, label)
        if k == mistake_at:
            if label == "any":
                if not out:
                    raise ValueError("a repeated pose needs a pose before it")
                out.append(replace(out[-1], label=f"{out[-1].label} again (mistake)"))
            else:
                wrong = {"+x": "+y", "-x": "+y", "+y": "+x", "-y": "+x", "+z": "+x",
                         "-z": "+x"}[label]
                out.append(pose(AXES[wrong], 0.0, f"{wrong} (mistake: {label} expected)"))
        out.append(p)
    return out


def with_sensor_errors(rig: Rig, seed: int,
                       max_misalignment_deg: float = MAX_MISALIGNMENT_DEG,
                       max_scale_error: float = MAX_SCALE_ERROR,
                       max_cross_axis: float = MAX_CROSS_AXIS,
                       max_offset_mps2: float = MAX_OFFSET_MPS2) -> Rig:
    """`rig` with random unknown errors on every sensor, uniform within the bounds: a
    misalignment of uniform size ≤ max about a random axis, per-axis scale, cross-axis terms and
    offsets. Any calibration already in the rig (S, offset) is removed."""
    rng = np.random.default_rng([seed, 3])
    links = {}
    for ln in LINK_NAMES:
        sensors = []
        for s in rig.links[ln].sensors:
            axis = rng.standard_normal(3)
            axis /= np.linalg.norm(axis)
            phi = axis * rng.uniform(0.0, max_misalignment_deg)
            scale = rng.uniform(-max_scale_error, max_scale_error, 3)
            cross = rng.uniform(-max_cross_axis, max_cross_axis, 6)
            bias = rng.uniform(-max_offset_mps2, max_offset_mps2, 3)
            sensors.append(replace(
                s, S=None, offset=None,
                sim_misalignment_deg=(float(phi[0]), float(phi[1]), float(phi[2])),
                sim_scale_error=(float(scale[0]), float(scale[1]), float(scale[2])),
                sim_cross_axis=(float(cross[0]), float(cross[1]), float(cross[2]),
                                float(cross[3]), float(cross[4]), float(cross[5])),
                sim_bias_mps2=(float(bias[0]), float(bias[1]), float(bias[2]))))
        links[ln] = LinkConfig(joint=rig.links[ln].joint, sensors=tuple(sensors))
    return replace(rig, links=links)
