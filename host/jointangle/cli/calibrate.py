"""`jointangle calibrate`: fit each sensor's S and offset from a recording of static poses.

Offline form: `--poses POSES.csv` is an accelerations CSV (docs/design.md §4) recorded while the rig
was held still in a sequence of poses and moved between them. Still poses are found
automatically; each sensor is fitted, graded and its noise measured; the calibrated rig is
written to `--out` only when every sensor passes. `--simulate-poses` writes such a recording
from the simulator instead (optionally after giving the rig unknown errors) to try it out.
Without `--poses`: the guided flow against a board (cli/calibrate_guided.py).
`--method motion --input DATA.csv`: the rig's geometry (positions, mountings, joints) fitted
from free joint motion instead (calibration/motion.py); `--out` gets the rig with it.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from jointangle.calibration.motion import (
    MotionPrior,
    calibrate_motion,
    motion_calibrated_rig,
)
from jointangle.calibration.pipeline import (
    ALIGNMENTS,
    METHODS,
    CalibrationReport,
    calibrate_recording,
    calibrated_rig,
)
from jointangle.calibration.reference import (
    ReferenceResult,
    measure_reference,
    referenced_rig,
)
from jointangle.cli.calibrate_guided import add_arguments as add_guided_arguments
from jointangle.cli.calibrate_guided import run_guided
from jointangle.cli.common import nonnegative_int, positive_float, refuse_overwrite
from jointangle.cli.motion_report import (
    motion_doc,
    print_motion_report,
    print_reference,
    reference_doc,
)
from jointangle.errors import InputError
from jointangle.io.atomic import check_output_paths
from jointangle.io.csv_formats import AccelData, read_accel_csv, write_accel_csv
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.rig import Rig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.static_poses import (
    AXES,
    axis_poses,
    pose,
    random_poses,
    static_pose_recording,
    with_sensor_errors,
)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "calibrate", help="fit sensor calibration (S, offset) from recorded static poses",
        description="Fit every sensor's calibration â = S v + o from a recording of static "
        "poses (an accelerations CSV). Still poses are detected automatically. Method "
        "'poses' (the paper's Appendix IV) needs ≥ 4 distinct poses with the link axes along "
        "±g (6-7 recommended: ±x, ±y, ±z); method 'gravity' (Madgwick §6.2) takes ≥ 9 "
        "arbitrary still orientations, plus two link poses (e.g. flat on the bench and link "
        "pointing up) or a fiducial sensor for the alignment. Each sensor is graded (A/B/C) "
        "and its noise measured while still; a poor fit is rejected with the reason and "
        "nothing is written (exit status 1). Without --poses: the guided flow against a board "
        "(--port; sim://native when no board is attached): it asks for each pose, shows a "
        "'hold still' indicator, rejects a hold that is not still or not along the asked axis, "
        "fits, writes S and offset to the board, saves them to EEPROM, reads them back to "
        "confirm, and writes the calibrated rig to a new file (or --out; the original rig file "
        "is never lost).")
    p.add_argument("--rig", help="rig file describing the build (needed except for sim:// "
                   "boards, which default to the gravity rig)")
    p.add_argument("--poses", help="accelerations CSV recorded through the static poses")
    p.add_argument("--out", help="calibrated rig file to write (S, offset and the measured "
                   "noise density of every sensor)")
    p.add_argument("--method", choices=[*METHODS, "motion"], default="poses",
                   help="poses (default): Appendix IV least squares; gravity: Madgwick §6.2; "
                   "motion: the geometry (each sensor's position and in-plane mounting, each "
                   "link's joint) from 30-60 s of free joint motion in --input, by maximum a "
                   "posteriori over the whole recording (trajectory and geometry together); "
                   "reports each lever arm and mounting with its σ and grade, says what the "
                   "motion could not identify, refuses (nothing written, exit 1) a recording "
                   "too short, clipped, too still or that the model does not fit")
    motion = p.add_argument_group("--method motion")
    motion.add_argument("--input", metavar="DATA.csv",
                        help="accelerations CSV of the joint moving freely, both links "
                        "turning briskly both ways (30-60 s)")
    motion.add_argument("--position-tolerance-mm", type=positive_float, default=2.0,
                        help="how far the rig's sensor positions may be off, ± per axis "
                        "(default 2)")
    motion.add_argument("--joint-tolerance-mm", type=positive_float, default=2.0,
                        help="how far the rig's joints may be off, ± per axis (default 2)")
    motion.add_argument("--mounting-tolerance-deg", type=positive_float, default=0.5,
                        help="how far the in-plane mountings may be off, ± (default 0.5; 0.2 "
                        "after the static-pose calibration, 1 for sensors mounted by eye); "
                        "also what keeps each link's x axis, which motion cannot see")
    motion.add_argument("--reference", metavar="POSE.csv",
                        help="accelerations CSV of the rig held still at a known joint angle "
                        "(--reference-angle-deg; straight against a straightedge or in a "
                        "fixture, hinge axis horizontal, 2-5 s): the joint's zero, which "
                        "motion cannot see (calibration/reference.py); without it each link's "
                        "x axis stays where the mounting tolerance keeps it")
    motion.add_argument("--reference-angle-deg", type=float, default=0.0,
                        help="the joint angle θ_ab of the --reference pose (default 0)")
    p.add_argument("--align", choices=list(ALIGNMENTS), default="link-poses",
                   help="alignment for --method gravity: to identified link poses (default) "
                   "or to the first sensor of each link (fiducial)")
    p.add_argument("--gravity", type=positive_float, default=STANDARD_GRAVITY,
                   help=f"local gravity in m/s² (default {STANDARD_GRAVITY})")
    p.add_argument("--no-noise", action="store_true",
                   help="do not write the measured noise densities into the rig")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    sim = p.add_argument_group("simulation (to try the command without hardware)")
    sim.add_argument("--simulate-poses", metavar="CSV",
                     help="instead of fitting, write a simulated static-pose recording of "
                     "--rig to CSV (uses the rig's sim_* error fields)")
    sim.add_argument("--pose-set", choices=("axis", "random"), default="axis",
                     help="axis: the paper's 7 holds (default); random: 32 arbitrary "
                     "orientations plus flat and link-up")
    sim.add_argument("--seed", type=nonnegative_int, default=0, help="noise seed (default 0)")
    sim.add_argument("--inject-errors", type=nonnegative_int, metavar="SEED",
                     help="first give every sensor random unknown errors (misalignment ≤ 3°, "
                     "scale ≤ 5 %%, cross-axis ≤ 100 mg/g, offsets ≤ 100 mg) and write that rig "
                     "to --rig-out; in the guided flow on a sim:// board, the board's "
                     "sensors have them")
    sim.add_argument("--rig-out", help="where --inject-errors writes the rig")
    add_guided_arguments(p)
    p.set_defaults(func=run)


def _simulate(args: argparse.Namespace, rig: Rig) -> int:
    check_output_paths({"--simulate-poses": args.simulate_poses, "--rig-out": args.rig_out})
    if args.inject_errors is not None:
        if not args.rig_out:
            raise InputError("--inject-errors needs --rig-out to say where the rig goes",
                             field="--rig-out")
        rig = with_sensor_errors(rig, args.inject_errors)
        write_rig(rig, args.rig_out)
    if args.pose_set == "axis":
        poses = axis_poses()
    else:
        poses = random_poses(32, np.random.default_rng([args.seed, 11]),
                             min_axis_distance_deg=30.0)
        poses += [pose(AXES["+z"], 0.0, "+z"), pose(AXES["+x"], 0.0, "+x")]
    rec = static_pose_recording(rig, poses, seed=args.seed)
    write_accel_csv(args.simulate_poses, rig, AccelData(t=rec.t, readings=rec.readings))
    print(f"wrote {len(poses)} static poses ({len(rec.t)} samples) to {args.simulate_poses}"
          + (f" and the rig with injected errors to {args.rig_out}"
             if args.inject_errors is not None else ""), file=sys.stderr)
    if args.json:
        json.dump({"poses": len(poses), "samples": len(rec.t), "out": str(args.simulate_poses),
                   "rig_out": str(args.rig_out) if args.inject_errors is not None else None},
                  sys.stdout)
        sys.stdout.write("\n")
    return 0


def _refuse_conflicts(args: argparse.Namespace) -> None:
    """Options that the chosen mode would ignore are refused, not dropped silently."""
    if args.poses and args.simulate_poses:
        raise InputError("use either --poses (calibrate a recording) or --simulate-poses "
                         "(write one), not both", field="--simulate-poses")
    if args.poses and (args.inject_errors is not None or args.rig_out):
        raise InputError("only with --simulate-poses or the guided flow: --poses calibrates "
                         "the recording as it is",
                         field="--inject-errors" if args.inject_errors is not None
                         else "--rig-out")
    if args.rig_out and args.inject_errors is None:
        raise InputError("is written only with --inject-errors", field="--rig-out")


def _vec(v: tuple[float, float, float] | None, digits: int = 1) -> str:
    return "—" if v is None else "/".join(f"{x:.{digits}f}" for x in v)


def report_doc(report: CalibrationReport) -> dict[str, Any]:
    return {
        "accepted": report.accepted,
        "method": report.method,
        "alignment": report.alignment,
        "reasons": report.reasons(),
        "poses": [{
            "t_start": p.segment.t_start, "t_stop": p.segment.t_stop,
            "axis": p.axis, "axis_error_deg": p.axis_error_deg, "excluded": p.reason,
        } for p in report.poses],
        "sensors": [{
            "sensor": s.label, "grade": s.grade, "reason": s.reason, "poses": s.poses,
            "distinct_poses": s.distinct_poses,
            "residual_mg_rms": None if np.isnan(s.residual_mg_rms) else s.residual_mg_rms,
            "magnitude_residual_mg_rms": None if np.isnan(s.magnitude_residual_mg_rms)
            else s.magnitude_residual_mg_rms,
            "alignment_residual_deg": s.alignment_residual_deg,
            "condition": None if not np.isfinite(s.condition) else s.condition,
            "noise_sigma_mg": s.noise_sigma_mg, "noise_density_ug": s.noise_density_ug,
            "S": None if s.S is None else s.S.tolist(),
            "offset": None if s.offset is None else s.offset.tolist(),
        } for s in report.sensors],
    }


def print_report(report: CalibrationReport, console: Console) -> None:
    console.print(f"{len(report.poses)} still poses found "
                  f"({sum(p.reason is None for p in report.poses)} used)")
    for k, p in enumerate(report.poses):
        axes = ", ".join(f"link {ln}: {ax or f'{p.axis_error_deg[ln]:.0f}° off-axis'}"
                         for ln, ax in p.axis.items())
        note = f"  excluded: {p.reason}" if p.reason else ""
        console.print(f"  pose {k + 1}: t {p.segment.t_start:.1f}-{p.segment.t_stop:.1f} s, "
                      f"{axes}{note}")
    table = Table(title=f"calibration ({report.method})", title_justify="left")
    for col in ("sensor", "grade", "poses", "residual mg", "|a|−g mg", "cond",
                "σ mg x/y/z", "µg/√Hz x/y/z"):
        table.add_column(col, justify="left" if col in ("sensor", "grade") else "right")
    for s in report.sensors:
        table.add_row(s.label, s.grade, f"{s.poses} ({s.distinct_poses})",
                      f"{s.residual_mg_rms:.2f}", f"{s.magnitude_residual_mg_rms:.2f}",
                      f"{s.condition:.1f}", _vec(s.noise_sigma_mg, 2),
                      _vec(s.noise_density_ug, 0))
    console.print(table)
    for r in report.reasons():
        console.print(f"rejected {r}")


def _run_motion(args: argparse.Namespace) -> int:
    for opt, val in (("--poses", args.poses), ("--simulate-poses", args.simulate_poses),
                     ("--inject-errors", args.inject_errors), ("--rig-out", args.rig_out)):
        if val is not None:
            raise InputError("is not used by --method motion (it fits --input)", field=opt)
    if not args.rig:
        raise InputError("is required with --method motion", field="--rig")
    if not args.input:
        raise InputError("is required with --method motion: the accelerations CSV of free "
                         "joint motion", field="--input")
    refuse_overwrite({"--rig": args.rig, "--input": args.input, "--reference": args.reference},
                     {"--out": args.out})
    if args.out:
        check_output_paths({"--out": args.out})
    rig = load_rig(args.rig)
    data = read_accel_csv(args.input, rig)
    if len(data.t) > 1:
        rate = 1.0 / float(np.median(np.diff(data.t)))
        if abs(rate - rig.sample_rate_hz) > 0.05 * rig.sample_rate_hz:
            rig = rig.with_sample_rate(rate)
    prior = MotionPrior(position_tol_m=args.position_tolerance_mm * 1e-3,
                        joint_tol_m=args.joint_tolerance_mm * 1e-3,
                        mounting_tol_deg=args.mounting_tolerance_deg)
    err = Console(stderr=True)
    with err.status("fitting the geometry to the motion…") as status:
        report = calibrate_motion(rig, data.t, data.readings, prior, progress=lambda i, c: (
            status.update(f"fitting the geometry to the motion: iteration {i}, cost {c:.6g}")))
    fitted = motion_calibrated_rig(load_rig(args.rig), report) if report.accepted else None
    zero: ReferenceResult | None = None
    if args.reference and fitted is not None:
        pose = read_accel_csv(args.reference, fitted)
        zero = measure_reference(fitted, pose.readings, args.reference_angle_deg)
        if zero.accepted:
            fitted = referenced_rig(fitted, zero)
    doc = motion_doc(report)
    if zero is not None:
        doc["reference"] = reference_doc(zero)
        doc["accepted"] = report.accepted and zero.accepted
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    else:
        out = Console()
        print_motion_report(report, out if out.is_terminal else Console(width=120))
        if zero is not None:
            print_reference(zero, out if out.is_terminal else Console(width=120))
    if fitted is None or (zero is not None and not zero.accepted):
        print("motion calibration rejected: nothing written", file=sys.stderr)
        return 1
    if args.out:
        write_rig(fitted, args.out)
        print(f"wrote the rig with the fitted geometry to {args.out}", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    if args.method == "motion":
        return _run_motion(args)
    if args.input:
        raise InputError("is for --method motion; static poses go in --poses", field="--input")
    if args.reference:
        raise InputError("is for --method motion (the joint's zero after the geometry fit)",
                         field="--reference")
    _refuse_conflicts(args)
    if not args.poses and not args.simulate_poses:
        # The guided flow keeps the original next to it when --out is the rig file.
        return run_guided(args, print_report, report_doc)
    if not args.rig:
        raise InputError("is required with --poses and --simulate-poses", field="--rig")
    refuse_overwrite({"--rig": args.rig, "--poses": args.poses},
                     {"--out": args.out, "--simulate-poses": args.simulate_poses,
                      "--rig-out": args.rig_out})
    rig = load_rig(args.rig)
    if args.simulate_poses:
        return _simulate(args, rig)
    data = read_accel_csv(args.poses, rig)
    if len(data.t) > 1:
        rate = 1.0 / float(np.median(np.diff(data.t)))
        if abs(rate - rig.sample_rate_hz) > 0.05 * rig.sample_rate_hz:
            rig = rig.with_sample_rate(rate)  # windows and noise density follow the data
    report = calibrate_recording(rig, data.t, data.readings, args.method, args.align,
                                 gravity_mps2=args.gravity)
    if args.json:
        json.dump(report_doc(report), sys.stdout)
        sys.stdout.write("\n")
    else:
        out = Console()
        print_report(report, out if out.is_terminal else Console(width=120))
    if not report.accepted:
        print("calibration rejected: nothing written", file=sys.stderr)
        return 1
    if args.out:
        cal = calibrated_rig(load_rig(args.rig), report, noise=not args.no_noise)
        write_rig(cal, args.out)
        print(f"wrote the calibrated rig to {args.out}", file=sys.stderr)
    return 0

