"""From a recording of static poses to a verified per-sensor calibration (or the reason not).

1. Still segments are found automatically (`stillness.detect_still`); each one is a pose.
   A segment that crept during its hold, or in which a sensor sits at its range, is excluded
   with the reason.
2. Each pose is identified per link: the link's sensors' mean reading, turned into the link
   frame by the nominal mounting, is compared with the six link axes; within
   `snap_tolerance_deg` it is a known pose "link axis along +g" (the paper's poses, §V and
   Appendix IV), otherwise an arbitrary orientation (usable by the gravity-magnitude fit only).
3. Per sensor, by method:
   - "poses" (Appendix IV): â_j = g · axis_j in the nominal sensor frame; `fit_linear`.
   - "gravity" (Madgwick §6.2.1–6.2.2): `fit_gravity_magnitude` over every still pose, then
     `fit_alignment` of the intrinsically calibrated readings onto the identified link poses
     (align="link-poses", needs two non-parallel ones) or onto a fiducial sensor of the same
     link (align="fiducial", Madgwick's choice; the fiducial's own axes are taken as nominal).
4. Checks, each with a reason: too few distinct poses, a pose set that does not span the
   sphere (ill-conditioned), a residual too large; a grade from the residual RMS.
5. Each sensor's noise measured in the still segments (σ per axis and µg/√Hz).
A calibration is accepted only when every sensor is; nothing should be written otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from jointangle.calibration.fit import (
    fit_alignment,
    fit_gravity_magnitude,
    fit_linear,
)
from jointangle.calibration.stillness import (
    DEFAULT_STILLNESS,
    NoiseEstimate,
    StillnessSettings,
    StillSegment,
    detect_still,
    measure_noise,
)
from jointangle.rig import LINK_NAMES, LinkConfig, Rig
from jointangle.sensors import STANDARD_GRAVITY

METHODS = {
    "poses": "linear least squares over poses with link axes along ±g (paper, Appendix IV)",
    "gravity": "gravity-magnitude fit over arbitrary still orientations, then alignment "
               "(Madgwick §6.2.1-6.2.2)",
}
ALIGNMENTS = ("link-poses", "fiducial")
GRADES = ("A", "B", "C")
MG = STANDARD_GRAVITY * 1e-3  # m/s² per mg

_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                 dtype=float)
_AXIS_LABELS = ("+x", "-x", "+y", "-y", "+z", "-z")


@dataclass(frozen=True)
class QualitySettings:
    snap_tolerance_deg: float = 15.0  # a pose within this of a link axis is "axis along +g"
    distinct_deg: float = 10.0  # poses closer than this count once
    min_poses_linear: int = 4  # Appendix IV: four independent poses at least
    min_poses_magnitude: int = 9  # 9 unknowns (T symmetric, c)
    min_alignment_poses: int = 2
    align_tolerance_deg: float = 15.0  # calibrated direction this close to an axis: candidate
    align_outlier_deg: float = 0.5  # candidates left further than this from the fit: dropped
    max_condition_linear: float = 30.0  # of [v/g 1]; six axis poses give √3
    max_condition_magnitude: float = 200.0  # of the column-scaled Jacobian
    min_spread: float = 0.05  # smallest eigenvalue of mean(d dᵀ) over distinct directions
    grade_limits_mg: tuple[float, float, float] = (1.0, 3.0, 10.0)  # A, B, C; above: rejected
    saturation_fraction: float = 0.98  # of the sensor's range


DEFAULT_QUALITY = QualitySettings()


@dataclass(frozen=True)
class PoseInfo:
    """One still segment seen as a pose."""

    segment: StillSegment
    up: dict[str, np.ndarray]  # link -> measured "up" direction in the link frame (unit)
    axis: dict[str, str | None]  # link -> identified axis ("+x", …) or None
    axis_error_deg: dict[str, float]  # link -> angle to the nearest axis
    reason: str | None  # why the pose is not used (None: used)


@dataclass(frozen=True)
class SensorCalibration:
    """One sensor's result."""

    link: str
    index: int
    S: np.ndarray | None  # (3, 3)
    offset: np.ndarray | None  # (3,) m/s²
    poses: int
    distinct_poses: int
    residual_mg_rms: float  # fit residual: â components (poses) or magnitude (gravity)
    magnitude_residual_mg_rms: float  # | |S v + o| − g | over the poses used
    alignment_residual_deg: float | None  # RMS angle to the references (gravity method)
    condition: float
    grade: str  # "A", "B", "C" or "rejected"
    reason: str | None
    noise_sigma_mg: tuple[float, float, float] | None
    noise_density_ug: tuple[float, float, float] | None

    @property
    def label(self) -> str:
        return f"{self.link}.{self.index}"

    @property
    def accepted(self) -> bool:
        return self.reason is None


@dataclass(frozen=True)
class CalibrationReport:
    method: str
    alignment: str | None
    poses: list[PoseInfo]
    sensors: list[SensorCalibration]
    noise: NoiseEstimate | None

    @property
    def accepted(self) -> bool:
        return bool(self.sensors) and all(s.accepted for s in self.sensors)

    def reasons(self) -> list[str]:
        return [f"{s.label}: {s.reason}" for s in self.sensors if s.reason is not None]


def _link_rotation(rotation_deg: float) -> np.ndarray:
    """3×3 taking nominal-sensor-frame components to link-frame ones (about z)."""
    c, s = np.cos(np.radians(rotation_deg)), np.sin(np.radians(rotation_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _distinct(dirs: np.ndarray, tol_deg: float) -> np.ndarray:
    """Representatives of the directions (P, 3) more than tol apart (greedy clustering)."""
    reps: list[np.ndarray] = []
    cos_tol = np.cos(np.radians(tol_deg))
    for d in dirs:
        if all(float(d @ r) < cos_tol for r in reps):
            reps.append(d)
    return np.array(reps).reshape(-1, 3)


def _spread(dirs: np.ndarray) -> float:
    """Smallest eigenvalue of mean(d dᵀ): 1/3 for poses evenly over the axes, 0 when every
    direction lies in one plane through the origin (nothing to fix the third axis)."""
    if len(dirs) == 0:
        return 0.0
    return float(np.linalg.eigvalsh(dirs.T @ dirs / len(dirs))[0])


def identify_poses(rig: Rig, segments: list[StillSegment],
                   quality: QualitySettings = DEFAULT_QUALITY) -> list[PoseInfo]:
    """Each segment's measured "up" per link and the link axis it lies along, if any."""
    sensors = rig.all_sensors()
    out = []
    for seg in segments:
        up: dict[str, np.ndarray] = {}
        axis: dict[str, str | None] = {}
        err: dict[str, float] = {}
        for ln in LINK_NAMES:
            vecs = [_link_rotation(s.rotation_deg) @ seg.mean[k]
                    for k, (lk, _, s) in enumerate(sensors) if lk == ln]
            d = np.mean([v / np.linalg.norm(v) for v in vecs], axis=0)
            d = d / np.linalg.norm(d)
            cosines = _AXES @ d
            best = int(np.argmax(cosines))
            ang = float(np.degrees(np.arccos(np.clip(cosines[best], -1.0, 1.0))))
            up[ln] = d
            err[ln] = ang
            axis[ln] = _AXIS_LABELS[best] if ang <= quality.snap_tolerance_deg else None
        reason = seg.reason
        if reason is None:
            for k, (ln, i, s) in enumerate(sensors):
                full = s.range_g * STANDARD_GRAVITY * quality.saturation_fraction
                if np.any(np.abs(seg.mean[k]) >= full):
                    reason = f"sensor {ln}.{i} saturated (±{s.range_g} g range)"
                    break
        out.append(PoseInfo(seg, up, axis, err, reason))
    return out


def _grade(residual_mg: float, quality: QualitySettings) -> str | None:
    for name, limit in zip(GRADES, quality.grade_limits_mg, strict=True):
        if residual_mg <= limit:
            return name
    return None


def _fit_poses(v: np.ndarray, poses: list[PoseInfo], link: str, rotation_deg: float,
               g: float, quality: QualitySettings
               ) -> tuple[np.ndarray | None, np.ndarray | None, dict[str, float], str | None]:
    """Appendix IV on the axis poses of one sensor. Returns S, o, figures, reason."""
    used = [k for k, p in enumerate(poses) if p.axis[link] is not None]
    figs = {"poses": float(len(used)), "distinct": 0.0, "residual": float("nan"),
            "magnitude": float("nan"), "condition": float("inf")}
    axes_dirs = np.array([_AXES[_AXIS_LABELS.index(str(poses[k].axis[link]))]
                          for k in used]).reshape(-1, 3)
    distinct = _distinct(axes_dirs, quality.distinct_deg)
    figs["distinct"] = float(len(distinct))
    if len(distinct) < quality.min_poses_linear:
        off = [p.axis_error_deg[link] for p in poses if p.axis[link] is None]
        hint = (f"; {len(off)} other poses are not along a link axis (the closest is "
                f"{min(off):.0f}° off; method 'gravity' takes arbitrary orientations)"
                if off else "")
        return None, None, figs, (
            f"too few distinct poses: {len(distinct)} with link {link}'s axes along ±g, "
            f"need ≥ {quality.min_poses_linear} (6-7 recommended: ±x, ±y, ±z){hint}")
    if _spread(distinct) < quality.min_spread:
        return None, None, figs, (
            "ill-conditioned pose set: the poses lie in one plane; add poses along the "
            "missing axis (±x, ±y, ±z all needed)")
    rot = _link_rotation(rotation_deg)
    a = g * axes_dirs @ rot  # nominal-sensor-frame components: rotᵀ (g · axis)
    fit = fit_linear(v[used], a, g)
    figs["condition"] = fit.condition
    if fit.condition > quality.max_condition_linear:
        return None, None, figs, (f"ill-conditioned pose set (condition number "
                                  f"{fit.condition:.0f} > {quality.max_condition_linear:g})")
    figs["residual"] = float(np.sqrt(np.mean(fit.residuals**2)) / MG)
    cal = v[used] @ fit.S.T + fit.offset
    figs["magnitude"] = float(np.sqrt(np.mean((np.linalg.norm(cal, axis=1) - g) ** 2)) / MG)
    return fit.S, fit.offset, figs, None


def _fit_magnitude(v: np.ndarray, poses: list[PoseInfo], g: float, quality: QualitySettings
                   ) -> tuple[np.ndarray | None, np.ndarray | None, dict[str, float],
                              str | None]:
    """Madgwick §6.2.1 on every usable pose of one sensor: intrinsic T, c."""
    dirs = v / np.linalg.norm(v, axis=1, keepdims=True)
    distinct = _distinct(dirs, quality.distinct_deg)
    figs = {"poses": float(len(v)), "distinct": float(len(distinct)),
            "residual": float("nan"), "magnitude": float("nan"), "condition": float("inf")}
    if len(distinct) < quality.min_poses_magnitude:
        return None, None, figs, (
            f"too few distinct poses: {len(distinct)} still orientations, the gravity-"
            f"magnitude fit needs ≥ {quality.min_poses_magnitude} (12 or more, spread over "
            "the sphere, recommended)")
    if _spread(distinct) < quality.min_spread:
        return None, None, figs, ("ill-conditioned pose set: the orientations lie near one "
                                  "plane; turn the rig over its third axis too")
    fit = fit_gravity_magnitude(v, g)
    figs["condition"] = fit.condition
    if not fit.success or fit.condition > quality.max_condition_magnitude:
        return None, None, figs, (f"ill-conditioned pose set (condition number "
                                  f"{fit.condition:.0f} > {quality.max_condition_magnitude:g})")
    figs["residual"] = float(np.sqrt(np.mean(fit.residuals**2)) / MG)
    figs["magnitude"] = figs["residual"]
    return fit.T, fit.c, figs, None


# One sensor's fit in progress: index, figures, reason, S, o, alignment residual (deg).
_Partial = tuple[int, dict[str, float], str | None, np.ndarray | None, np.ndarray | None,
                 float | None]


def calibrate_segments(rig: Rig, segments: list[StillSegment], readings: np.ndarray | None,
                       method: str = "poses", alignment: str = "link-poses",
                       fiducials: dict[str, int] | None = None,
                       gravity_mps2: float = STANDARD_GRAVITY,
                       quality: QualitySettings = DEFAULT_QUALITY) -> CalibrationReport:
    """Calibrate every sensor of `rig` from its still segments (see the module doc).

    `readings` (T, n, 3), when given, is used to measure each sensor's noise.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}")
    if alignment not in ALIGNMENTS:
        raise ValueError(f"unknown alignment {alignment!r}")
    g = gravity_mps2
    poses_all = identify_poses(rig, segments, quality)
    usable = [p for p in poses_all if p.reason is None]
    noise = measure_noise(rig, readings, segments) if readings is not None else None
    sensors = rig.all_sensors()
    v_all = np.array([p.segment.mean for p in usable]).reshape(len(usable), len(sensors), 3)
    results: list[SensorCalibration] = []
    # Intrinsic fits first (gravity method), so fiducial alignment can use its fiducial.
    intrinsic: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    pending: list[_Partial] = []
    for k, (ln, _i, s) in enumerate(sensors):
        v = v_all[:, k, :]
        align_res: float | None = None
        if method == "poses":
            S, o, figs, reason = _fit_poses(v, usable, ln, s.rotation_deg, g, quality)
        else:
            T, c, figs, reason = _fit_magnitude(v, usable, g, quality)
            S, o = None, None
            if T is not None and c is not None:
                intrinsic[k] = (T, c)
        pending.append((k, figs, reason, S, o, align_res))
    if method == "gravity":
        pending = _align_all(rig, usable, v_all, intrinsic, pending, alignment,
                             fiducials or {}, quality)
    for k, figs, reason, S, o, align_res in pending:
        ln, i, s = sensors[k]
        grade = "rejected"
        if not poses_all:
            reason = ("no still pose found: hold the rig still for a few seconds in each "
                      "pose")
        elif not usable:
            reason = (f"no usable pose: all {len(poses_all)} still segments were excluded "
                      f"(first: {poses_all[0].reason})")
        if reason is None:
            gr = _grade(figs["residual"], quality)
            if gr is None:
                reason = (f"residual too large: {figs['residual']:.1f} mg RMS > "
                          f"{quality.grade_limits_mg[-1]:g} mg (a pose not held still, or "
                          "not along the axis it was taken for)")
            else:
                grade = gr
                if method == "poses" and figs["distinct"] <= quality.min_poses_linear:
                    grade = "C"  # exactly determined: nothing left over to check the fit
        sig = dens = None
        if noise is not None:
            sg = noise.sigma_mps2[k] / MG
            dn = noise.density_ug[k]
            sig = (float(sg[0]), float(sg[1]), float(sg[2]))
            dens = (float(dn[0]), float(dn[1]), float(dn[2]))
        results.append(SensorCalibration(
            link=ln, index=i, S=S if reason is None else None,
            offset=o if reason is None else None, poses=int(figs["poses"]),
            distinct_poses=int(figs["distinct"]), residual_mg_rms=figs["residual"],
            magnitude_residual_mg_rms=figs["magnitude"], alignment_residual_deg=align_res,
            condition=figs["condition"], grade=grade, reason=reason, noise_sigma_mg=sig,
            noise_density_ug=dens))
    return CalibrationReport(method=method, alignment=alignment if method == "gravity" else None,
                             poses=poses_all, sensors=results, noise=noise)


def _align_all(rig: Rig, usable: list[PoseInfo], v_all: np.ndarray,
               intrinsic: dict[int, tuple[np.ndarray, np.ndarray]],
               pending: list[_Partial], alignment: str, fiducials: dict[str, int],
               quality: QualitySettings) -> list[_Partial]:
    """Madgwick §6.2.2 for every intrinsically calibrated sensor: S = R T, o = R c."""
    sensors = rig.all_sensors()
    first = {ln: next(k for k, (lk, _, _) in enumerate(sensors) if lk == ln)
             for ln in LINK_NAMES}
    out: list[_Partial] = []
    for k, figs, reason, _S, _o, _a in pending:
        ln, _i, s = sensors[k]
        if reason is not None or k not in intrinsic:
            out.append((k, figs, reason, None, None, None))
            continue
        T, c = intrinsic[k]
        u = v_all[:, k, :] @ T.T + c
        rot = _link_rotation(s.rotation_deg)
        if alignment == "link-poses":
            # Candidates: poses whose intrinsically calibrated direction, in the link frame by
            # the nominal mounting, lies within align_tolerance_deg of a link axis. What is
            # left there is the misalignment plus the antisymmetric part of the cross-axis
            # terms (a magnitude cannot tell it from a rotation): up to ~10°. An arbitrary
            # pose that happens to fall near an axis is found by its residual below and
            # dropped, worst first, while two non-parallel poses remain.
            d_link = u @ rot.T
            d_link = d_link / np.linalg.norm(d_link, axis=1, keepdims=True)
            cosines = d_link @ _AXES.T
            best = np.argmax(cosines, axis=1)
            close = cosines[np.arange(len(u)), best] >= np.cos(
                np.radians(quality.align_tolerance_deg))
            idx = [j for j in range(len(u)) if close[j]]
            ref_link = _AXES[best[idx]].reshape(-1, 3)
            src = "identified link poses"
        else:
            fk = first[ln] + fiducials.get(ln, 0)
            if fk not in intrinsic:
                out.append((k, figs, f"fiducial sensor {ln}.{fk - first[ln]} has no "
                            "intrinsic calibration", None, None, None))
                continue
            Tf, cf = intrinsic[fk]
            idx = list(range(len(usable)))
            ref_link = (v_all[:, fk, :] @ Tf.T + cf) @ _link_rotation(
                sensors[fk][2].rotation_deg).T
            src = f"fiducial sensor {ln}.{fk - first[ln]}"
        distinct = _distinct(ref_link / np.linalg.norm(ref_link, axis=1, keepdims=True),
                             quality.distinct_deg)
        if len(distinct) < quality.min_alignment_poses:
            out.append((k, figs, f"alignment needs ≥ {quality.min_alignment_poses} "
                        f"non-parallel {src} (e.g. flat on the bench and link pointing up); "
                        f"found {len(distinct)}", None, None, None))
            continue
        ref = ref_link @ rot  # into the sensor's nominal frame: rotᵀ r
        al = fit_alignment(u[idx], ref)
        # Drop the worst pose while it disagrees with the fit and what remains still has a
        # majority to outvote the next one (three poses, two directions); with no such
        # redundancy a disagreement cannot be settled and the fit is rejected.
        keep = np.arange(len(idx))
        while np.degrees(al.residuals.max()) > quality.align_outlier_deg and len(keep) > 3:
            rest = np.delete(keep, int(np.argmax(al.residuals)))
            if len(_distinct(ref[rest], quality.distinct_deg)) < quality.min_alignment_poses:
                break
            keep = rest
            al = fit_alignment(u[np.asarray(idx)[keep]], ref[keep])
        worst = float(np.degrees(al.residuals.max()))
        if worst > quality.align_outlier_deg:
            out.append((k, figs, f"{src} disagree: one is {worst:.1f}° from the fitted "
                        f"alignment (> {quality.align_outlier_deg:g}°) and too few agree to "
                        "outvote it; a pose taken for a link axis was not along it — "
                        "re-take the link poses", None, None, None))
            continue
        S = al.R @ T
        o = al.R @ c
        out.append((k, figs, None, S, o,
                    float(np.degrees(np.sqrt(np.mean(al.residuals**2))))))
    return out


def calibrate_recording(rig: Rig, t: np.ndarray, readings: np.ndarray, method: str = "poses",
                        alignment: str = "link-poses", fiducials: dict[str, int] | None = None,
                        gravity_mps2: float = STANDARD_GRAVITY,
                        stillness: StillnessSettings = DEFAULT_STILLNESS,
                        quality: QualitySettings = DEFAULT_QUALITY) -> CalibrationReport:
    """Detect the still poses in a recording (T, n, 3) and calibrate every sensor."""
    segments = detect_still(rig, t, readings, stillness)
    return calibrate_segments(rig, segments, readings, method, alignment, fiducials,
                              gravity_mps2, quality)


def calibrated_rig(rig: Rig, report: CalibrationReport, *, noise: bool = True) -> Rig:
    """`rig` with each sensor's S and offset (and, with `noise`, its measured noise density)
    from an accepted report. Raises ValueError for a rejected one: nothing is to be written."""
    if not report.accepted:
        raise ValueError("calibration rejected: " + "; ".join(report.reasons()))
    by_label = {r.label: r for r in report.sensors}
    links = {}
    for ln in LINK_NAMES:
        new = []
        for i, s in enumerate(rig.links[ln].sensors):
            r = by_label[f"{ln}.{i}"]
            assert r.S is not None and r.offset is not None
            upd = replace(s, S=tuple(tuple(float(x) for x in row) for row in r.S),
                          offset=(float(r.offset[0]), float(r.offset[1]), float(r.offset[2])))
            # A density of 0 means the noise was below the quantisation (not measured): the
            # rig file keeps what it had (a rig file's density must be > 0).
            if noise and r.noise_density_ug is not None and min(r.noise_density_ug) > 0:
                upd = replace(upd, noise_density_ug=r.noise_density_ug)
            new.append(upd)
        links[ln] = LinkConfig(joint=rig.links[ln].joint, sensors=tuple(new))
    return replace(rig, links=links)
