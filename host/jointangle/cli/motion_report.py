"""The reports of the geometry calibration (`calibrate --method motion` and the guided flow's
motion step): JSON documents and the printed tables."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.table import Table

from jointangle.calibration.motion import MotionReport
from jointangle.calibration.reference import ReferenceResult


def motion_doc(report: MotionReport) -> dict[str, Any]:
    return {
        "accepted": report.accepted, "method": "motion", "reasons": report.reasons,
        "seconds": report.seconds, "samples": report.samples, "decimation": report.decimation,
        "iterations": report.iterations, "cost_start": report.cost_start,
        "cost_end": report.cost_end,
        "sensors": [{
            "sensor": s.label, "grade": s.grade,
            "lever_nominal_m": list(s.lever_nominal_m), "lever_m": list(s.lever_m),
            "lever_sigma_m": list(s.lever_sigma_m), "lever_length_sigma_m": s.length_sigma_m,
            "moved_m": s.moved_m, "mounting_deg": s.mounting_deg,
            "mounting_sigma_deg": s.mounting_sigma_deg,
            "relative_mounting_sigma_deg": s.relative_mounting_sigma_deg,
            "residual_mg_rms": s.residual_mg_rms, "residual_to_noise": s.residual_ratio,
        } for s in report.sensors],
        "links": [{
            "link": g.link, "joint_offset_m": list(g.joint_offset_m), "alpha_rms": g.alpha_rms,
            "omega2_rms": g.omega2_rms, "common_rotation_sigma_deg": g.common_rotation_sigma_deg,
        } for g in report.links],
        "not_identified": NOT_IDENTIFIED,
    }


NOT_IDENTIFIED = [
    "where each link's frame origin is: only lever arms (sensor position − joint) enter, so "
    "sensors and joint move together by the least the tolerances allow",
    "the direction of each link's x axis (a common turn of its mountings and lever arms changes "
    "only θ by a constant): it stays where the mounting tolerance puts it (σ in "
    "common_rotation_sigma_deg) unless --reference gives the joint's zero",
]


def print_motion_report(report: MotionReport, console: Console) -> None:
    console.print(f"{report.seconds:.1f} s of motion, {report.samples} samples"
                  + (f" (every {report.decimation}th)" if report.decimation > 1 else "")
                  + (f"; {report.iterations} iterations, cost {report.cost_start:.4g} → "
                     f"{report.cost_end:.4g}" if report.iterations else ""))
    for g in report.links:
        console.print(f"  link {g.link}: RMS α {g.alpha_rms:.2f} rad/s², RMS ω² "
                      f"{g.omega2_rms:.2f} rad²/s²; joint moved by "
                      f"{g.joint_offset_m[0] * 1e3:+.2f}, {g.joint_offset_m[1] * 1e3:+.2f} mm; "
                      f"x axis kept to ±{g.common_rotation_sigma_deg:.3f}° (not identifiable)")
    if report.sensors:
        table = Table(title="geometry from motion (lever arm = position − joint)",
                      title_justify="left")
        for col in ("sensor", "grade", "lever drawn mm", "lever fitted mm", "σ x/y/along mm",
                    "mounting °", "σ rel °", "residual mg", "× noise"):
            table.add_column(col, justify="left" if col in ("sensor", "grade") else "right")
        for s in report.sensors:
            table.add_row(
                s.label, s.grade,
                f"{s.lever_nominal_m[0] * 1e3:.2f}, {s.lever_nominal_m[1] * 1e3:.2f}",
                f"{s.lever_m[0] * 1e3:.2f}, {s.lever_m[1] * 1e3:.2f}",
                f"{s.lever_sigma_m[0] * 1e3:.2f}/{s.lever_sigma_m[1] * 1e3:.2f}/"
                f"{s.length_sigma_m * 1e3:.2f}",
                f"{s.mounting_deg:+.3f}", f"{s.relative_mounting_sigma_deg:.3f}",
                f"{s.residual_mg_rms:.2f}", f"{s.residual_ratio:.2f}")
        console.print(table)
        console.print("not identifiable from motion: " + "; ".join(NOT_IDENTIFIED))
    for r in report.reasons:
        console.print(f"rejected: {r}")


def reference_doc(r: ReferenceResult) -> dict[str, Any]:
    return {"accepted": r.accepted, "reasons": r.reasons,
            "theta_measured_deg": r.theta_measured_deg,
            "theta_reference_deg": r.theta_reference_deg, "offset_deg": r.offset_deg,
            "sigma_deg": r.sigma_deg, "samples": r.samples}


def print_reference(r: ReferenceResult, console: Console) -> None:
    if r.accepted:
        console.print(f"joint's zero: the reference pose reads {r.theta_measured_deg:+.3f}° "
                      f"(reference {r.theta_reference_deg:g}°, σ {r.sigma_deg:.3f}° from "
                      f"{r.samples} samples): links a, b turned by {-r.offset_deg / 2:+.3f}°, "
                      f"{r.offset_deg / 2:+.3f}°")
    for reason in r.reasons:
        console.print(f"rejected reference pose: {reason}")
