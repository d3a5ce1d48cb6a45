"""Planar two-link mechanisms: link angles, rates and accelerations over time.

Both mechanisms have link a's frame origin on a fixed pivot; link a carries the hinge O at
r_O^a (its frame), and link b's frame has O at r_O^b. World angles θ_a, θ_b are measured from
the world x axis; the joint angle is θ_ab = θ_a − θ_b (docs/design.md §3).

Acceleration of a point at r on a link, in that link's frame (Appendix I, eq. 1):
    a = a_origin + D(r) [ω², α]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointangle.sim.motion import Motion


@dataclass(frozen=True)
class LinkKinematics:
    theta: np.ndarray  # rad, world angle of the link x axis
    omega: np.ndarray  # rad/s
    alpha: np.ndarray  # rad/s²


@dataclass(frozen=True)
class MechanismState:
    t: np.ndarray
    a: LinkKinematics
    b: LinkKinematics
    joint_a: tuple[float, float]  # r_O in link a's frame (m)
    joint_b: tuple[float, float]  # r_O in link b's frame (m)

    @property
    def theta_ab(self) -> np.ndarray:
        return self.a.theta - self.b.theta


def _rotate(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """World components of link-frame vectors v (T, ..., 2) for link angle θ (T,)."""
    c = np.cos(theta)
    s = np.sin(theta)
    while c.ndim < v.ndim - 1:
        c = c[..., None]
        s = s[..., None]
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _unrotate(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    return _rotate(-theta, v)


def _rigid_accel(k: LinkKinematics, r: np.ndarray) -> np.ndarray:
    """D(r)[ω², α] for points r (N, 2): acceleration relative to the frame origin (T, N, 2)."""
    w2 = (k.omega**2)[:, None]
    al = k.alpha[:, None]
    return np.stack([-r[:, 0] * w2 - r[:, 1] * al, -r[:, 1] * w2 + r[:, 0] * al], axis=-1)


def point_positions_world(m: MechanismState, link: str, r: np.ndarray) -> np.ndarray:
    """World positions (T, N, 2) of points r (N, 2) on a link (used by kinematics tests)."""
    r = np.asarray(r, dtype=float)
    joint_world = _rotate(m.a.theta, np.broadcast_to(np.array(m.joint_a), (len(m.t), 1, 2)))
    if link == "a":
        return _rotate(m.a.theta, np.broadcast_to(r, (len(m.t), *r.shape)))
    rel = r - np.array(m.joint_b)
    return joint_world + _rotate(m.b.theta, np.broadcast_to(rel, (len(m.t), *r.shape)))


def point_accelerations_link(m: MechanismState, link: str, r: np.ndarray) -> np.ndarray:
    """Kinematic acceleration (T, N, 2) of points r (N, 2) on `link`, in that link's frame."""
    r = np.asarray(r, dtype=float)
    if link == "a":
        return _rigid_accel(m.a, r)
    # Joint acceleration from link a, expressed in the world, then in link b's frame.
    a_joint_a = _rigid_accel(m.a, np.array([m.joint_a]))  # (T, 1, 2) in frame a
    a_joint_world = _rotate(m.a.theta, a_joint_a)
    a_joint_b = _unrotate(m.b.theta, a_joint_world)
    return a_joint_b + _rigid_accel(m.b, r - np.array(m.joint_b))


def slider_crank(t: np.ndarray, crank: Motion, la: float, lb: float) -> MechanismState:
    """The paper's slider-crank (Appendix III): crank a of length L_a, connecting rod b of L_b.

    With λ = L_a/L_b:  θ_b = asin(−λ sin θ_a),  ω_b = −λ (cos θ_a / cos θ_b) ω_a,
    α_b = λ (sin θ_a (ω_a² − ω_b²) − cos θ_a α_a) / cos θ_b.
    Link a's frame origin is the crank pivot (joint at [L_a, 0]); link b's frame origin is the
    joint (x towards the slider).
    """
    lam = la / lb
    th_a, w_a, al_a = crank(t)
    th_b = np.arcsin(-lam * np.sin(th_a))
    w_b = -lam * (np.cos(th_a) / np.cos(th_b)) * w_a
    al_b = lam * (np.sin(th_a) * (w_a**2 - w_b**2) - np.cos(th_a) * al_a) / np.cos(th_b)
    return MechanismState(
        t=t,
        a=LinkKinematics(th_a, w_a, al_a),
        b=LinkKinematics(th_b, w_b, al_b),
        joint_a=(la, 0.0),
        joint_b=(0.0, 0.0),
    )


def two_link(t: np.ndarray, link_a: Motion, link_b: Motion, joint_a: tuple[float, float],
             joint_b: tuple[float, float] = (0.0, 0.0)) -> MechanismState:
    """Two links on a fixed pivot with prescribed world angles (link a may be held still)."""
    ka = LinkKinematics(*link_a(t))
    kb = LinkKinematics(*link_b(t))
    return MechanismState(t=t, a=ka, b=kb, joint_a=joint_a, joint_b=joint_b)


def specific_force_link(m: MechanismState, link: str, r: np.ndarray,
                        gravity_world: np.ndarray) -> np.ndarray:
    """What ideal accelerometers at r (N, 2) on `link` read, in the link frame (T, N, 3).

    Specific force f = a − g: gravity_world is g as a 3-vector in the world frame whose x, y span
    the plane of motion (e.g. [0, −9.81, 0] for a horizontal hinge, [0, 0, −9.81] for a
    horizontal mechanism).
    """
    acc = point_accelerations_link(m, link, r)
    theta = m.a.theta if link == "a" else m.b.theta
    g_plane = np.broadcast_to(np.asarray(gravity_world[:2], dtype=float), acc.shape)
    g_link = _unrotate(theta, g_plane)
    f_xy = acc - g_link
    f_z = np.full((*acc.shape[:-1], 1), -float(gravity_world[2]))
    return np.concatenate([f_xy, f_z], axis=-1)
