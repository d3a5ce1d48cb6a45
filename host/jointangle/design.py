"""Sensor placement: predicted errors by simulation and by Cramér–Rao-style bounds, the
recommendation `jointangle design` prints, and the paper's placement studies (Figs. 5–7).

Notation (Woods & Vikas §IV, docs/design.md §5): on each link the array's mean position r̄ lies l/2
from the joint and the sensors span the relative length d along the link (two sensors at
l/2 ± d/2; N sensors evenly over that span).

Per-sample bound (memoryless estimators, e.g. `analytical`). The joint's specific force from
link j is v_j = F_j a_j (eq. 8) with covariance F_j Q̂_j F_jᵀ. Because F_m Gᵀ = 0 and
G Gᵀ = (D̃ᵀD̃)⁻¹ = I / Σ|r_i − r̄|² (model.py), for isotropic noise σ² per axis

    F_j F_jᵀ = κ_j I,   κ_j = 1/N_j + |r_O − r̄_j|² / Σ_i |r_i − r̄_j|²

and θ = angle between v_a and v_b has Fisher information |v|² / (σ² (κ_a + κ_b)) per sample:

    var θ̂_k ≥ σ² (κ_a + κ_b) / |v_k|²                                             (CRB₀)

With two sensors (Σ|r̃|² = d²/2, |r_O − r̄| = l/2) κ = 1/2 + (l/d)²/2: the error grows with l,
falls with 1/d, and the link with the larger l/d sets the floor — the paper's Figs. 6–7.

More sensors (the paper's Fig. 5). κ has an averaging term 1/N and a lever term (l/2)²/Σ|r̃|².
N sensors evenly over a fixed span d (the paper's §IV layout) have Σ|r̃|² = d² N (N+1) / (12 (N−1)):

    κ_span(N) = 1/N + 3 (l/d)² (N−1) / (N (N+1))          (= 1/2 + (l/d)²/2 at N = 2)

N sensors stacked half at each end of the same span have Σ|r̃|² = N d²/4:

    κ_ends(N) = (1 + (l/d)²) / N                           (pure √N averaging)

In the noise-limited regime every estimator's error scales as √κ, so 2 → N sensors multiply it by
√(κ(N)/κ(2)); at l = d and N = 10 that is 0.59 (span) and 0.45 (ends). N κ_span(N) grows from
1 + (l/d)² to 1 + 3 (l/d)²: a sensor added inside the span averages noise but adds little lever,
so each one is worth less than the last (2κ(2)/κ(N) "ideal" sensors: 5.8 of 10 at l = d). Neither
term touches an estimator's start-up from x₀ = 0, so a score that includes the start-up sees less.

Dynamic bound (filters). For the raw-reading model of `array-ekf` (linear Gauss–Markov motion
prior, readings h(s) + white noise) the posterior Cramér–Rao bound (Tichavský et al. 1998) obeys
the information recursion evaluated on the true trajectory,

    J_k = (Φ J_{k−1}⁻¹ Φᵀ + Q)⁻¹ + H(s_k)ᵀ R⁻¹ H(s_k)                               (PCRB)

which is the Kalman covariance recursion with H at the truth; √(J⁻¹)_θθ is the best RMS any
estimator can reach *under that prior*. It is a model-relative bound (a smoother motion prior
would lower it), and cheap: no noise is drawn, so it ranks placements without seeds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from jointangle.estimators.array_kf import (
    DEFAULT_Q_ALPHA,
    DEFAULT_Q_JOINT,
    I_JX,
    I_JY,
    I_TH,
    I_WA,
    I_WB,
    N_STATE,
    ArrayModel,
    discretise,
)
from jointangle.estimators.base import full_noise_variance, sensor_to_link, wrap
from jointangle.estimators.inputs import run_estimator
from jointangle.estimators.registry import get_estimator
from jointangle.model import rig_model
from jointangle.rig import LinkConfig, Rig, SensorConfig
from jointangle.sensors import SENSOR_MODELS
from jointangle.sim.mechanism import MechanismState, slider_crank, specific_force_link
from jointangle.sim.motion import Sine
from jointangle.sim.scenarios import get_scenario, simulate_rig

STEADY_S = 5.0
ADDRESSES = (0x53, 0x1D)  # two I2C addresses per mux channel
MUX_CHANNELS = 8
MAX_BUS_SENSORS = MUX_CHANNELS * len(ADDRESSES)  # a rig file can address 16 chips at most


@dataclass(frozen=True)
class Motion:
    """A reference motion for a build: mechanism over time and gravity (world frame)."""

    mech: MechanismState
    gravity_world: np.ndarray
    label: str


def build_rig(la: float, lb: float, dist_a: Sequence[float], dist_b: Sequence[float],
              model: str = "adxl345", rate_hz: float = 100.0,
              noise_ug: float | None = None, quantize: bool = True,
              offset_a: Sequence[float] | None = None, offset_b: Sequence[float] | None = None,
              name: str = "design") -> Rig:
    """A rig with sensors at the given distances from the joint along each link (link a's
    joint at [L_a, 0], link b's at [0, 0]); optional perpendicular offsets (off-axis)."""
    spec = SENSOR_MODELS[model]
    density = None if noise_ug is None else (noise_ug, noise_ug, noise_ug)
    k = 0

    def sensors(dists: Sequence[float], sign: float, base: float,
                offsets: Sequence[float] | None) -> tuple[SensorConfig, ...]:
        nonlocal k
        out = []
        for i, d in enumerate(dists):
            y = 0.0 if offsets is None else float(offsets[i])
            out.append(SensorConfig(model=model, position=(base + sign * float(d), y),
                                    mux_channel=(k // 2) % MUX_CHANNELS, address=ADDRESSES[k % 2],
                                    range_g=spec.ranges_g[0], noise_density_ug=density,
                                    quantize=quantize))
            k += 1
        return tuple(out)

    link_a = LinkConfig(joint=(la, 0.0), sensors=sensors(dist_a, -1.0, la, offset_a))
    link_b = LinkConfig(joint=(0.0, 0.0), sensors=sensors(dist_b, 1.0, 0.0, offset_b))
    return Rig(name=name, sample_rate_hz=rate_hz, links={"a": link_a, "b": link_b})


def spread(l_mean: float, d_rel: float, n: int) -> list[float]:
    """Distances from the joint of n sensors with mean l/2 spanning d (the paper's §IV)."""
    return list(np.linspace(l_mean / 2 - d_rel / 2, l_mean / 2 + d_rel / 2, n))


def reference_motion(name: str, la: float, lb: float, rate_hz: float = 100.0,
                     seconds: float = 30.0) -> Motion:
    """The motion of a named scenario, on links of the given lengths.

    paper-*: the slider-crank with crank L_a, rod L_b (θ_a = 45° sin(2π·0.2 Hz·t)); gravity-*:
    link a clamped level, link b moving as in that scenario (link lengths only bound where
    sensors can go).
    """
    t = np.arange(round(seconds * rate_hz)) / rate_hz
    sc = get_scenario(name)
    if name.startswith("paper-"):
        mech = slider_crank(t, Sine(np.radians(45.0), 0.2), la, lb)
    else:
        mech = replace(sc.mechanism(t), joint_a=(la, 0.0))
    return Motion(mech, np.asarray(sc.gravity_world, dtype=float), name)


def true_states(rig: Rig, motion: Motion) -> np.ndarray:
    """The array model's state along the truth (T, N_STATE); only θ, ω, j enter H."""
    m = motion.mech
    s = np.zeros((len(m.t), N_STATE))
    s[:, I_TH] = m.theta_ab
    s[:, I_WA] = m.a.omega
    s[:, I_WB] = m.b.omega
    j = specific_force_link(m, "a", np.array([rig.links["a"].joint]), motion.gravity_world)
    s[:, I_JX] = j[:, 0, 0]
    s[:, I_JY] = j[:, 0, 1]
    return s


def pcrb_theta(rig: Rig, motion: Motion, q_alpha: float = DEFAULT_Q_ALPHA,
               q_joint: float = DEFAULT_Q_JOINT) -> np.ndarray:
    """√(J⁻¹)_θθ over time (rad) from the PCRB recursion on the true trajectory."""
    model = ArrayModel(rig)
    Phi, Q = discretise(rig.dt, q_alpha, q_joint)
    Rinv = np.diag(1.0 / full_noise_variance(rig))
    s = true_states(rig, motion)
    H = model.H(s)  # (T, M, n)
    info = np.einsum("tmi,mn,tnj->tij", H, Rinv, H)
    P = np.diag([np.pi**2, 4.0, 4.0, 100.0, 100.0, 10.0, 10.0, 10.0, 10.0, 1e3, 1e3])
    out = np.empty(len(s))
    for k in range(len(s)):
        if k > 0:
            P = Phi @ P @ Phi.T + Q
        J = np.linalg.inv(P) + info[k]
        P = np.linalg.inv(J)
        P = 0.5 * (P + P.T)
        out[k] = np.sqrt(max(P[I_TH, I_TH], 0.0))
    return out


def kappa(rig: Rig, link: str) -> float:
    """κ_j = trace(F_j F_jᵀ)/2: the joint-force noise gain of one array (isotropic noise)."""
    arr = rig_model(rig).a if link == "a" else rig_model(rig).b
    return float(np.trace(arr.F @ arr.F.T) / 2.0)


def crb0_theta(rig: Rig, motion: Motion) -> np.ndarray:
    """Per-sample bound √(σ² (κ_a + κ_b)) / |v_k| over time (rad), σ² the mean reading
    variance; needs no filter and no prior."""
    m = rig_model(rig)
    var = full_noise_variance(rig)
    ca = np.trace((m.a.F * var[: m.na]) @ m.a.F.T) / 2.0
    cb = np.trace((m.b.F * var[m.na :]) @ m.b.F.T) / 2.0
    j = specific_force_link(motion.mech, "a", np.array([rig.links["a"].joint]),
                            motion.gravity_world)[:, 0, :2]
    return np.sqrt((ca + cb) / np.maximum(np.sum(j**2, -1), 1e-12))


def kappa_span(n: int, l_mean: float, d_rel: float) -> float:
    """κ of n sensors evenly over the span d with mean l/2 from the joint (closed form above)."""
    return 1.0 / n + 3.0 * (l_mean / d_rel) ** 2 * (n - 1) / (n * (n + 1))


def kappa_ends(n: int, l_mean: float, d_rel: float) -> float:
    """κ of n (even) sensors stacked half at each end of the span d (closed form above)."""
    return (1.0 + (l_mean / d_rel) ** 2) / n


def ends(l_mean: float, d_rel: float, n: int) -> list[float]:
    """Distances of n sensors stacked half at each end of the span (far end gets an odd one)."""
    return [l_mean / 2 - d_rel / 2] * (n // 2) + [l_mean / 2 + d_rel / 2] * (n - n // 2)


def count_gain(la: float, lb: float, dist_a: Sequence[float], dist_b: Sequence[float],
               ns: Sequence[int] = (4, 6, 10)) -> list[dict[str, float]]:
    """What more sensors on the same spans buy: for each N, the noise-limited error factor
    √((κ_a + κ_b)(N) / (κ_a + κ_b)(2)) relative to two sensors at each link's extremes, with
    the N sensors evenly over the span (`even`) or stacked half at each end (`ends`)."""

    def total(fa: Sequence[float], fb: Sequence[float]) -> float:
        rig = build_rig(la, lb, fa, fb, noise_ug=400.0, quantize=False)
        return kappa(rig, "a") + kappa(rig, "b")

    def layouts(d: Sequence[float], n: int) -> tuple[list[float], list[float]]:
        lo, hi = min(d), max(d)
        return [float(x) for x in np.linspace(lo, hi, n)], [lo] * (n // 2) + [hi] * (n - n // 2)

    k2 = total(layouts(dist_a, 2)[0], layouts(dist_b, 2)[0])
    out = []
    for n in ns:
        (ea, sa), (eb, sb) = layouts(dist_a, n), layouts(dist_b, n)
        out.append({"n": n, "even": float(np.sqrt(total(ea, eb) / k2)),
                    "ends": float(np.sqrt(total(sa, sb) / k2))})
    return out


def steady_rms(x: np.ndarray, t: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x[..., t >= STEADY_S]))))


def simulate_errors(rig: Rig, motion: Motion, filters: Sequence[str], seeds: Sequence[int]
                    ) -> dict[str, np.ndarray]:
    """Steady RMS θ error (degrees) per seed for each filter, all seeds in one batch."""
    return {f: w["steady"] for f, w in simulate_windows(rig, motion, filters, seeds).items()}


def simulate_windows(rig: Rig, motion: Motion, filters: Sequence[str], seeds: Sequence[int]
                     ) -> dict[str, dict[str, np.ndarray]]:
    """RMS θ error (degrees) per seed for each filter over three windows: `steady` (t ≥ 5 s),
    `start` (t < 5 s) and `full` (the whole run, the paper's Table II / Fig. 5 score)."""
    readings = np.stack([simulate_rig(rig, motion.mech, motion.gravity_world, s)
                         for s in seeds])
    acc = sensor_to_link(rig, readings)
    t = motion.mech.t
    out = {}
    for f in filters:
        est = run_estimator(get_estimator(f), rig, acc)
        sq = np.degrees(wrap(est.theta - motion.mech.theta_ab[None])) ** 2
        out[f] = {"steady": np.sqrt(np.mean(sq[:, t >= STEADY_S], axis=1)),
                  "start": np.sqrt(np.mean(sq[:, t < STEADY_S], axis=1)),
                  "full": np.sqrt(np.mean(sq, axis=1))}
    return out


@dataclass(frozen=True)
class Candidate:
    dist_a: tuple[float, ...]
    dist_b: tuple[float, ...]
    pcrb_deg: float
    crb0_deg: float


def link_options(L: float, n: int, margin: float) -> list[list[float]]:
    """Placements of n sensors on a link of length L: spread evenly between a near and a far
    distance from the joint on a grid (and, for n ≥ 4, half at each of the two)."""
    grid = np.linspace(margin, L - margin, 5)
    opts = []
    for i, near in enumerate(grid):
        for far in grid[i + 1:]:
            opts.append([float(x) for x in np.linspace(near, far, n)])
            if n > 3:
                half = n // 2
                opts.append([float(near)] * (n - half) + [float(far)] * half)
    return opts


def rank_placements(la: float, lb: float, n: int, motion: Motion, model: str, rate_hz: float,
                    noise_ug: float | None, margin: float) -> list[Candidate]:
    """Candidate placements ranked by their PCRB (best first). Coordinate search: link a's
    options with link b at its extremes, then link b's options with link a's best — 2 × 10
    bounds instead of 100 (the bound is nearly separable: the worse link sets the floor)."""
    t = motion.mech.t

    def evaluate(da: list[float], db: list[float]) -> Candidate:
        rig = build_rig(la, lb, da, db, model, rate_hz, noise_ug,
                        offset_a=_split_offsets(da), offset_b=_split_offsets(db))
        return Candidate(tuple(da), tuple(db),
                         float(np.degrees(steady_rms(pcrb_theta(rig, motion), t))),
                         float(np.degrees(steady_rms(crb0_theta(rig, motion), t))))

    ends_b = [float(x) for x in np.linspace(margin, lb - margin, n)]
    first = sorted((evaluate(da, ends_b) for da in link_options(la, n, margin)),
                   key=lambda c: c.pcrb_deg)
    best_a = list(first[0].dist_a)
    second = sorted((evaluate(best_a, db) for db in link_options(lb, n, margin)),
                    key=lambda c: c.pcrb_deg)
    return second + first


def _split_offsets(dists: Sequence[float]) -> list[float] | None:
    """Sensors stacked at the same distance sit 1 cm apart across the link (distinct chips)."""
    seen: dict[float, int] = {}
    offs = []
    for d in dists:
        key = round(float(d), 6)
        i = seen.get(key, 0)
        seen[key] = i + 1
        offs.append(0.01 * ((i + 1) // 2) * (1 if i % 2 else -1) if i else 0.0)
    return offs if any(offs) else None


