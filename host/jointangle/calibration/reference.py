"""The joint's zero: one still pose at a known joint angle fixes what motion cannot see.

Motion calibration (calibration/motion.py) fits every lever arm and each sensor's mounting
relative to the others on its link, but not the direction of a link's x axis. Turning link j's
frame by β — its x axis to angle β in the old frame — gives every sensor of that link the
mounting ρ_i − β and the position O_j + R₂(−β)(p_i − O_j): each sensor's reading and its lever
arm, expressed in the new frame, are the old ones turned by −β, so

    R₂(ρ_i − β) â_i = R₂(−β) R₂(ρ_i) â_i = R₂(−β) (a_O + D(r_i − r_O) y)
                     = R₂(−β) a_O + D(R₂(−β)(r_i − r_O)) y

(D(R u) y = R D(u) y for a rotation R: the centripetal term is −ω² u, the tangential α ẑ × u,
both equivariant) — every reading is explained equally well and only the joint vector seen
from that link turns: vᵃ = R(θ) vᵇ becomes vᵃ = R(θ − β) vᵇ' for a turn β of link b (R(θ) =
R₂(−θ), docs/design.md §3). So θ_ab shifts by a constant that no motion of the joint can reveal:
the likelihood of the recording is flat along β_a − β_b. It does matter to θ — by exactly that
constant — which is why it is fixed by a reference rather than left to the fit's prior.

A still pose at a known joint angle θ_ref (the rig held straight against a straightedge, or in
a fixture; the static calibration's "stand the straight rig on end" poses are such poses) gives
the missing constant: at rest each array measures gravity, θ_meas = eq. 12 on the mean joint
vectors, and link a is turned by −Δ/2, link b by +Δ/2 with Δ = θ_meas − θ_ref (only β_a − β_b
enters θ; splitting it keeps each link's own x axis as close as possible to where the static
calibration put it). Gravity must lie in the plane of motion (hinge axis horizontal), else the
pose says nothing about θ and is refused. σ of the result: the readings' noise averaged over
the hold, plus whatever the pose's own angle is off by (the user's reference), which passes
into θ unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from jointangle.estimators.analytical import analytical_theta, joint_vectors
from jointangle.estimators.base import full_noise_variance, sensor_to_link, wrap
from jointangle.model import rig_model
from jointangle.rig import Rig

MIN_IN_PLANE_G = 0.5  # of g: gravity's in-plane part needed to see θ at rest
MIN_SAMPLES = 20
MAX_CHANGE_DEG = 5.0  # a bigger correction is a wrong pose or a wrong reference angle


@dataclass(frozen=True)
class ReferenceResult:
    accepted: bool
    reasons: list[str]
    theta_measured_deg: float
    theta_reference_deg: float
    offset_deg: float  # Δ = θ_meas − θ_ref, removed by turning the links by ∓Δ/2
    sigma_deg: float  # from the readings' noise over the hold
    samples: int


def turn_link(rig: Rig, link: str, beta_deg: float) -> Rig:
    """`rig` with link `link`'s frame turned by β: its x axis to angle β in the old frame (every
    sensor's mounting − β, its position turned by −β about the joint)."""
    cfg = rig.links[link]
    o = np.asarray(cfg.joint, dtype=float)
    c, s = math.cos(math.radians(beta_deg)), math.sin(math.radians(beta_deg))
    sensors = []
    for sen in cfg.sensors:
        u = np.asarray(sen.position, dtype=float) - o
        p = o + np.array([c * u[0] + s * u[1], -s * u[0] + c * u[1]])
        sensors.append(replace(sen, position=(float(p[0]), float(p[1])),
                               rotation_deg=sen.rotation_deg - beta_deg))
    return replace(rig, links={**rig.links, link: replace(cfg, sensors=tuple(sensors))})


def measure_reference(rig: Rig, readings: np.ndarray, theta_ref_deg: float,
                      gravity_mps2: float = 9.80665) -> ReferenceResult:
    """θ at rest from a still hold (readings (T, n, 3), raw sensor frames) against θ_ref."""
    reasons: list[str] = []
    n = len(readings)
    if n < MIN_SAMPLES:
        reasons.append(f"the reference hold has {n} samples; at least {MIN_SAMPLES} needed")
        return ReferenceResult(False, reasons, math.nan, theta_ref_deg, math.nan, math.nan, n)
    acc = sensor_to_link(rig, readings)
    va, vb = joint_vectors(rig, acc)
    ma, mb = va.mean(axis=0), vb.mean(axis=0)
    theta = float(np.degrees(analytical_theta(ma, mb)))
    delta = float(np.degrees(wrap(np.radians(theta - theta_ref_deg))))
    # σ of each joint vector's mean (F Q̂ Fᵀ / T), projected across the vector (its angle)
    m = rig_model(rig)
    q = full_noise_variance(rig)
    var = 0.0
    for v, F, qq in ((ma, m.a.F, q[: m.na]), (mb, m.b.F, q[m.na:])):
        g = float(np.hypot(*v))
        if g < MIN_IN_PLANE_G * gravity_mps2:
            reasons.append(f"gravity in the plane of motion is {g / gravity_mps2:.2f} g (needs "
                           f"≥ {MIN_IN_PLANE_G:g} g): with the hinge axis near vertical a still "
                           "pose does not show the joint angle; hold the reference pose with "
                           "the hinge axis horizontal")
            g = max(g, 1e-9)
        perp = np.array([-v[1], v[0]]) / g
        var += float(perp @ (F * qq) @ F.T @ perp) / n / g**2
    moving = float(np.max(np.std(acc, axis=0)))
    if moving > 5.0 * float(np.sqrt(np.max(q))):
        reasons.append("the reference pose was not held still (readings spread "
                       f"{moving:.3f} m/s²)")
    if not reasons and abs(delta) > MAX_CHANGE_DEG:
        reasons.append(f"the pose reads {theta:.2f}° against the reference {theta_ref_deg:g}° "
                       f"(Δ {delta:.2f}°, limit ±{MAX_CHANGE_DEG:g}°): a different pose or a "
                       "wrong --reference-angle-deg")
    return ReferenceResult(not reasons, reasons, theta, theta_ref_deg, delta,
                           math.degrees(math.sqrt(var)), n)


def referenced_rig(rig: Rig, result: ReferenceResult) -> Rig:
    """`rig` with the links turned so that the reference pose reads θ_ref (module doc)."""
    d = result.offset_deg
    return turn_link(turn_link(rig, "a", -d / 2.0), "b", d / 2.0)


def combine_references(results: list[ReferenceResult]) -> ReferenceResult:
    """Several holds at the same known angle (the static calibration's straight poses): the
    accepted ones averaged, weighted by 1/σ²; refused if none was accepted."""
    ok = [r for r in results if r.accepted]
    if not ok:
        reasons = [r for res in results for r in res.reasons] or ["no reference pose"]
        return ReferenceResult(False, reasons, math.nan,
                               results[0].theta_reference_deg if results else math.nan,
                               math.nan, math.nan, sum(r.samples for r in results))
    w = np.array([1.0 / max(r.sigma_deg, 1e-9) ** 2 for r in ok])
    off = float(np.sum(w * [r.offset_deg for r in ok]) / np.sum(w))
    ref = ok[0].theta_reference_deg
    return ReferenceResult(True, [], ref + off, ref, off, float(1.0 / np.sqrt(np.sum(w))),
                           sum(r.samples for r in ok))
