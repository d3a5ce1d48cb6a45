"""`jointangle bench firmware`: the ATmega2560 figures of docs/design.md §4/§5, measured in simavr.

- Step cycles: `avr_cycles` runs the `bench_filter` image on every step of every scenario's full
  run (seed 0, `write_core_input`; firmware/core/FILTER.md "Full runs by hand") and reports the
  worst step of the fixed-point and of the float build of the same filter source.
- The loop: the real image (`jointangle_mega2560.elf`) on the AVR virtual board (`ja_avr_board`,
  firmware/sim/avr_board/README.md) with a four-ADXL345 rig and the simulated motion, streaming
  to this host over its pty. Once the stream runs, SIGUSR1 opens the board's measurement window;
  it ends `window_s` simulated seconds later and the board writes its report: cycles per
  activity id (GPIOR1), sleep cycles, bus occupancy at a real 400 kHz computed from the bytes on
  the bus, stack high-water mark. The frames received in the window tell whether every frame
  carried four fresh samples and whether the firmware counted overruns or UART drops.
- The highest sustainable loop rate: the same run at increasing rig rates until a rate is not
  sustained (loop rate below the rate, overruns, stale samples or UART drops), for four ADXL345
  and for four BNO055. simavr does not model I2C clock stretching, which the BNO055 does.
Nothing is cached: every figure comes from this run on the images as built now.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jointangle.bench.parity import array_of, write_core_input
from jointangle.boards.options import LaunchOptions
from jointangle.boards.process import start_process_board
from jointangle.built import REPO_ROOT
from jointangle.errors import InputError
from jointangle.io.csv_formats import AccelData, Truth, write_accel_csv
from jointangle.io.rig_file import write_rig
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.link import Link
from jointangle.rig import LinkConfig
from jointangle.sim.scenarios import get_scenario, simulate
from jointangle.transport import open_serial

IMAGE = "jointangle_mega2560.elf"
BENCH_FILTER = "bench_filter.elf"
BENCH_FILTER_SECTIONS = "bench_filter_sections.elf"  # JA_BENCH_STEP_PROFILE
# The sections of core::Step, in order (joint_filter.hpp JA_STEP_MARK).
STEP_SECTIONS = ("rows_startup", "time_update", "measurement", "noise_blocks", "decorrelation",
                 "updates", "wrap_health")
TARGETS = ("avr_images", "avr_cycles", "ja_avr_board")
DEFAULT_RATE_HZ = 500
DEFAULT_WINDOW_S = 2.0
SWEEP_RATES_HZ = (100, 150, 200, 250, 300, 400, 500, 600, 700, 800, 900, 1000)  # 10-1000 Hz
REFINE_STEP_HZ = 5  # the bisection above the sweep's highest sustained rate stops at this
SETTLE_FRAMES = 50  # frames after start_stream before the window opens
# ... and not before this much device time: the first loops after boot configure the filter
# (float, once the sensors are first usable) and miss ~10 periods; a fast host used to open the
# window on top of that (9 overruns at 280 or 300 Hz on some runs, none on others).
SETTLE_DEVICE_US = 600_000
ACTIVITY_KEYS = {0: "main", 1: "twi_isr", 2: "usart_isr", 3: "filter", 4: "calibration",
                 5: "streaming", 6: "timer_isr", 7: "commands"}
NO_STRETCH_NOTE = ("simavr 1.6 does not model I2C clock stretching: the BNO055 stretches SCL "
                   "(up to ms around mode changes), so its real-bus rate may be lower")

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Artefacts:
    tree: Path
    avr_cycles: Path  # the cycle harness (the Pico's: pico_cycles.mjs, the same JSON)
    bench_filter: Path
    board: Path
    image: Path
    board_args: tuple[str, ...] = ()  # the board's own options before the image (the Pico's)


def build_trees(build_dir: Path | None) -> list[Path]:
    """`build_dir` (a configured CMake tree), else build/native and the other build/* trees."""
    if build_dir is not None:
        if not (build_dir / "CMakeCache.txt").is_file():
            raise InputError("not a configured CMake build tree (no CMakeCache.txt)",
                             path=build_dir)
        return [build_dir]
    build = REPO_ROOT / "build"
    others = sorted(p.parent for p in build.glob("*/CMakeCache.txt") if p.parent.name != "native")
    native = [build / "native"] if (build / "native" / "CMakeCache.txt").is_file() else []
    return native + others


def locate(build_dir: Path | None = None, *, build: bool = True,
           need_image: bool = True) -> Artefacts:
    """The build tree's artefacts, brought up to date first (`cmake --build --target
    avr_images avr_cycles ja_avr_board`) unless build=False. Errors name the missing target."""
    trees = build_trees(build_dir)
    if not trees:
        raise InputError("no configured build tree: run `cmake -S . -B build/native` (then "
                         "this bench builds what it needs)", field="--build-dir")
    tree = trees[0]
    if build:
        if shutil.which("cmake") is None:
            raise InputError("cmake is not installed (scripts/setup.sh)", field="--build-dir")
        res = subprocess.run(["cmake", "--build", str(tree), "--target", *TARGETS],
                             capture_output=True, text=True, check=False)
        if res.returncode != 0:
            tail = (res.stdout + res.stderr).strip().splitlines()[-3:]
            raise InputError(f"building {' '.join(TARGETS)} in {tree} failed: "
                             + " | ".join(t.strip()[:160] for t in tail), field="--build-dir")
    paths = {"avr_cycles": (tree / "firmware" / "avr_cycles", "avr_cycles"),
             "bench_filter": (tree / "avr" / BENCH_FILTER, "avr_images"),
             "board": (tree / "firmware" / "sim" / "ja_avr_board", "ja_avr_board"),
             "image": (tree / "avr" / IMAGE, "avr_images")}
    for key, (path, target) in paths.items():
        if key == "image" and not need_image:
            continue
        if not path.is_file():
            raise InputError(f"{path.name} is not built in {tree}: run `cmake --build {tree} "
                             f"--target {target}`", field="--build-dir")
    return Artefacts(tree, paths["avr_cycles"][0], paths["bench_filter"][0], paths["board"][0],
                     paths["image"][0])


# ---- Step cycles ---------------------------------------------------------------------------

def _filter_regions(elf: Path, avr_cycles: Path, data: Path) -> dict[str, Any]:
    """The cycle regions of a filter bench image run on the input file `data`."""
    res = subprocess.run([str(avr_cycles), "--max-cycles", "8000000000", "--input", str(data),
                          str(elf)], capture_output=True, text=True, check=False)
    try:
        doc = json.loads(res.stdout)
    except json.JSONDecodeError:
        raise InputError(f"avr_cycles gave no report (status {res.returncode}): "
                         f"{res.stderr.strip()[-300:]}", path=elf) from None
    if doc.get("state") != "done" or doc.get("marker_errors"):
        raise InputError(f"the filter bench did not finish cleanly: state {doc.get('state')}, "
                         f"marker errors {doc.get('marker_errors')}", path=elf)
    regions: dict[str, Any] = doc["regions"]
    return regions


def _write_input(workdir: Path, scenarios: Sequence[str] | None,
                 seconds: float | None, more_sensors: Sequence[str] = ()) -> tuple[Path, int]:
    data = workdir / "all.bin"
    return data, write_core_input(str(data), scenarios, seconds=seconds,
                                  more_sensors=more_sensors)


# Scenarios also run with 3 and 4 sensors per link (the filter takes 2 to 4): their steps are
# timed apart (`steps_by_sensors`), the headline figures stay those of 2 per link.
MORE_SENSORS_SCENARIOS = ("paper-table2-L20", "gravity-fast-periodic")


def _counted(regions: dict[str, Any], name: str, steps: int, elf: Path,
             also: str | None = None) -> dict[str, Any]:
    """Worst, mean and count of region `name`; with `also` (the release step's region, timed
    apart: once per filter start) its steps join the mean and the count, not the worst."""
    r = regions.get(name)
    extra = regions.get(also) if also else None
    count = (0 if r is None else r["count"]) + (0 if extra is None else extra["count"])
    if r is None or count < steps:
        raise InputError(f"the filter bench timed {count} {name} steps of {steps}", path=elf)
    mean = r["mean"] * r["count"] + (0.0 if extra is None else extra["mean"] * extra["count"])
    out = {"worst": r["net_max"], "mean": round(mean / count, 1), "count": count}
    if extra is not None:
        out["release_worst"] = extra["net_max"]
    return out


def step_cycles(art: Artefacts, workdir: Path, scenarios: Sequence[str] | None = None,
                seconds: float | None = None,
                more_sensors: Sequence[str] | None = None) -> dict[str, Any]:
    """Worst fixed and float filter step over every step of every scenario's full run (or of
    the first `seconds` of `scenarios`), two sensors a link, the release step (once per filter
    start) apart; and for 3 and 4 a link on `more_sensors` (default: MORE_SENSORS_SCENARIOS
    when every scenario runs, none otherwise)."""
    if more_sensors is None:
        more_sensors = MORE_SENSORS_SCENARIOS if scenarios is None else ()
    data, _ = _write_input(workdir, scenarios, seconds, more_sensors)
    regions = _filter_regions(art.bench_filter, art.avr_cycles, data)
    steps = sum(int(regions.get(n, {}).get("count", 0))
                for n in ("filter_fixed", "filter_fixed_release"))
    out: dict[str, Any] = {"steps": steps}
    for key in ("fixed", "float"):
        out[key] = _counted(regions, f"filter_{key}", 1, art.bench_filter,
                            also=f"filter_{key}_release" if not more_sensors else None)
    release = regions.get("filter_fixed_release")
    if release is not None:  # once per filter start (ReleaseSum): every sensor count
        out["release_step_cycles"] = {"fixed": release["net_max"],
                                      "float": regions["filter_float_release"]["net_max"],
                                      "count": release["count"]}
    by_n: dict[str, Any] = {}
    for n, suffix in ((2, ""), (3, "_n3"), (4, "_n4")):
        fixed, flt = regions.get(f"filter_fixed{suffix}"), regions.get(f"filter_float{suffix}")
        if fixed is None or flt is None:
            continue
        by_n[str(n)] = {"fixed_step_cycles": fixed["net_max"], "float_step_cycles": flt["net_max"],
                        "steps": fixed["count"]}
    out["by_sensors_per_link"] = by_n
    return out


def step_sections(art: Artefacts, workdir: Path, scenarios: Sequence[str] | None = None,
                  seconds: float | None = None) -> dict[str, Any]:
    """Cycles of each section of the filter step (worst and mean over the same steps as
    step_cycles, fixed and float), from the bench image built with JA_BENCH_STEP_PROFILE: the
    link rows and start-up, the time update, the measurement (sin/cos, h, y), the noise blocks
    (R), the decorrelation, the sequential updates, wrap and health. A section's worst step is
    not the whole step's worst, so the worsts add up to more than the step's."""
    elf = art.tree / "avr" / BENCH_FILTER_SECTIONS
    if not elf.is_file():
        raise InputError(f"{elf.name} is not built in {art.tree}: run `cmake --build "
                         f"{art.tree} --target avr_images`", field="--build-dir")
    data, steps = _write_input(workdir, scenarios, seconds)
    regions = _filter_regions(elf, art.avr_cycles, data)
    out: dict[str, Any] = {}
    for section in STEP_SECTIONS:
        names = {"fixed": f"fixed_{section}", "float": f"float_{section}"}
        if section == "rows_startup":  # the plain step's regions: the release step apart
            out[section] = {key: _counted(regions, f"filter_{key}", steps, elf,
                                          also=f"filter_{key}_release") for key in names}
            continue
        out[section] = {key: _counted(regions, name, steps, elf) for key, name in names.items()}
    return out


# ---- Flash and RAM -------------------------------------------------------------------------

def image_size(image: Path) -> tuple[int, int]:
    """(flash, static RAM) bytes as avr-size --format=avr reports them (Program, Data)."""
    tool = shutil.which("avr-size")
    if tool is None:
        raise InputError("avr-size is not installed (binutils-avr; scripts/setup.sh)",
                         field="avr-size")
    out = subprocess.run([tool, "--format=avr", "--mcu=atmega2560", str(image)],
                         capture_output=True, text=True, check=True).stdout
    prog = re.search(r"Program:\s+(\d+) bytes", out)
    data = re.search(r"Data:\s+(\d+) bytes", out)
    if prog is None or data is None:
        raise InputError(f"cannot read avr-size's output: {out[:200]!r}", path=image)
    return int(prog.group(1)), int(data.group(1))


# ---- The loop in the AVR virtual board ----------------------------------------------------

# What bench_rig changes when it swaps the gravity rig's ADXL345 for another model.
MODEL_ADDRESS = {"bno055": 0x28, "adxl357": 0x1D}
MODEL_RANGE_G = {"adxl357": 10}  # (the others keep the rig's)


def bench_rig(model: str, rate_hz: int, per_link: int = 2, channel_per_link: bool = False) -> Any:
    """The gravity rig (four sensors behind the TCA9548A, channels 0-3) at `rate_hz`, with
    every sensor made `model` (MODEL_ADDRESS, MODEL_RANGE_G); with per_link 3 or 4 ADXL345,
    that many a link over the same span (`bench.parity.array_of`, two a channel at 0x53, 0x1D).
    channel_per_link: the two ADXL345 of each link share its channel (link a on 0, b on 1) at
    0x53 and 0x1D, so a loop selects the multiplexer twice instead of four times."""
    rig = get_scenario("gravity-slow-periodic").rig(float(rate_hz))
    if channel_per_link:
        if model != "adxl345" or per_link != 2:
            raise ValueError("a channel per link: two ADXL345 a link (0x53 and 0x1D)")
        return dataclasses.replace(rig, links={
            name: dataclasses.replace(link, sensors=tuple(
                dataclasses.replace(s, mux_channel=li, address=(0x53, 0x1D)[j])
                for j, s in enumerate(link.sensors)))
            for li, (name, link) in enumerate(sorted(rig.links.items()))})
    if per_link != 2:
        if model != "adxl345":
            raise ValueError("more sensors per link: ADXL345 only (two addresses a channel)")
        return array_of(rig, per_link)
    if model == "adxl345":
        return rig
    links = {}
    for name, link in rig.links.items():
        sensors = tuple(dataclasses.replace(s, model=model, address=MODEL_ADDRESS[model],
                                            range_g=MODEL_RANGE_G.get(model, s.range_g))
                        for s in link.sensors)
        links[name] = LinkConfig(joint=link.joint, sensors=sensors)
    return dataclasses.replace(rig, links=links)


@dataclass
class LoopRun:
    """One board run: the board's report and what the frames in its window said."""

    rate_hz: int
    model: str
    report: dict[str, Any]
    frames: int
    frames_lost: int
    stale_frames: int  # a sample_estimate frame with a sensor whose `fresh` is 0
    overruns: int  # status.loop_overruns, last minus first seen in the window
    uart_drops: int

    @property
    def loop_rate_hz(self) -> float:
        """The board's count of loops (the Mega's activity markers), else the frames stamped in
        the window over its length (one sample frame a loop in the full stream)."""
        if "loop_rate_hz" in self.report:
            return float(self.report["loop_rate_hz"])
        return self.frames / self.report["seconds"] if self.report["seconds"] else 0.0

    def sustained(self, min_asleep: float = 0.0) -> tuple[bool, str]:
        """Held: the asked rate within 1 %, no overrun, stale sample, drop or loss, and at
        least `min_asleep` of the cycles asleep."""
        why = []
        if self.report["idle_fraction"] < min_asleep:
            why.append(f"{100 * self.report['idle_fraction']:.1f} % asleep")
        if self.loop_rate_hz < 0.99 * self.rate_hz:
            why.append(f"loop rate {self.loop_rate_hz:.0f} Hz")
        if self.overruns:
            why.append(f"{self.overruns} overruns")
        if self.stale_frames:
            why.append(f"{self.stale_frames} frames with a stale sample")
        if self.uart_drops or self.frames_lost:
            why.append(f"{self.uart_drops} UART drops, {self.frames_lost} frames lost")
        if self.frames == 0:
            why.append("no frames")
        return not why, ", ".join(why)


def run_loop(art: Artefacts, model: str, rate_hz: int, window_s: float,
             workdir: Path, per_link: int = 2, stream: str = "full",
             channel_per_link: bool = False) -> LoopRun:
    """Start the board on the image (fast clock), stream (`full`: sample_estimate frames;
    `estimates`: lean_estimate), open the window, collect frames until the board ends the run,
    read its report."""
    rig = bench_rig(model, rate_hz, per_link, channel_per_link)
    sim = simulate("gravity-slow-periodic", seed=0, rate_hz=float(rate_hz), seconds=10.0,
                   rig=rig)
    tag = f"{model}-{per_link}{'-paired' if channel_per_link else ''}-{stream}-{rate_hz}"
    per_loop = (msgs.SampleEstimate if stream == "full" else msgs.LeanEstimate).MSG_ID
    mode = (msgs.StreamMode.SAMPLE_ESTIMATE if stream == "full"
            else msgs.StreamMode.LEAN_ESTIMATE) | msgs.StreamMode.STATUS
    rig_path, motion, report = (workdir / f"rig-{tag}.toml", workdir / f"motion-{tag}.csv",
                                workdir / f"report-{tag}.json")
    write_rig(sim.rig, rig_path)
    write_accel_csv(motion, sim.rig, AccelData(t=sim.t, readings=sim.readings,
                                               truth=Truth(sim.theta, sim.omega_a,
                                                           sim.omega_b)))
    argv = [str(art.board), "--rig", str(rig_path), "--motion", str(motion), "--fast",
            "--loop-motion", "--report", str(report), "--measure-from", "1e6",
            "--measure-seconds", f"{window_s:g}", *art.board_args, str(art.image)]
    board = start_process_board(argv, LaunchOptions(start_timeout_s=30.0))
    frames: list[Any] = []
    try:
        port = open_serial(board.port_path)
        try:
            link = Link(port, timeout_s=2.0)
            for attempt in range(5):
                try:
                    link.handshake()
                    break
                except TimeoutError:
                    if attempt == 4:
                        raise
            link.command(msgs.StartStream(mode=int(mode), status_interval_ms=100))
            settled, device_us = 0, 0
            while settled < SETTLE_FRAMES or device_us < SETTLE_DEVICE_US:
                for f in link.poll():
                    if f.msg_id == per_loop:
                        settled += 1
                        device_us = f.t_us
                if board.process.poll() is not None:
                    raise InputError(f"the board exited before streaming "
                                     f"(status {board.process.returncode})", path=art.image)
            board.process.send_signal(signal.SIGUSR1)
            deadline = time.monotonic() + 120.0 * window_s
            while board.process.poll() is None and time.monotonic() < deadline:
                try:
                    frames += link.poll()
                except OSError:
                    break  # the board closed the pty at the end of the run
            stats = link.stats
        finally:
            port.close()
    finally:
        board.stop()
    if not report.is_file():
        raise InputError("the board wrote no report (it did not end its run)", path=report)
    rep = json.loads(report.read_text())
    # Frames stamped inside the window (the board runs a short tail after it so they all arrive).
    start_us = rep["window_start_s"] * 1e6
    end_us = start_us + rep["seconds"] * 1e6
    decoded = [(f.t_us, decode_message(f)) for f in frames
               if f.msg_id in (per_loop, msgs.Status.MSG_ID)]
    samples = [m for t, m in decoded if isinstance(m, msgs.SampleEstimate | msgs.LeanEstimate)
               and start_us <= t < end_us]
    # Overruns and drops inside the window only: counted from the first status seen, they
    # included whatever happened before the window (the stream's start, and on a fast host the
    # boot's filter configuration, SETTLE_DEVICE_US).
    status = [m for t, m in decoded if isinstance(m, msgs.Status) and start_us <= t < end_us]
    stale = sum(1 for m in samples
                if isinstance(m, msgs.SampleEstimate) and any(x.fresh == 0 for x in m.sensors))
    overruns = status[-1].loop_overruns - status[0].loop_overruns if len(status) > 1 else 0
    drops = status[-1].uart_drops - status[0].uart_drops if len(status) > 1 else 0
    return LoopRun(rate_hz, model, rep, len(samples), int(stats.get("frames_lost", 0)), stale,
                   overruns, drops)


def max_sustained_rate(art: Artefacts, model: str, window_s: float, workdir: Path,
                       progress: Progress, rates: Sequence[int] = SWEEP_RATES_HZ,
                       start_hz: int = DEFAULT_RATE_HZ, per_link: int = 2,
                       stream: str = "full", min_asleep: float = 0.0,
                       channel_per_link: bool = False) -> dict[str, Any]:
    """From `start_hz` up while sustained (until the first rate that is not), else down until
    one is: the highest sustained rate of `rates` (None if none is), then refined upwards in
    by bisection towards the next rate of `rates` (which was not sustained), to REFINE_STEP_HZ."""
    tried: dict[int, dict[str, Any]] = {}

    def attempt(rate: int) -> bool:
        progress(f"highest sustained rate: {2 * per_link} {model}, {stream} stream, at {rate} Hz")
        run = run_loop(art, model, rate, window_s, workdir, per_link, stream, channel_per_link)
        ok, why = run.sustained(min_asleep)
        tried[rate] = {"rate_hz": rate, "loop_rate_hz": round(run.loop_rate_hz, 1),
                       "sustained": ok, "why": why,
                       "idle_fraction": round(run.report["idle_fraction"], 4),
                       "bus_occupancy": round(run.report["bus"]["occupancy"], 4)}
        return ok

    i = rates.index(start_hz)
    best: int | None = None
    if attempt(rates[i]):
        best = rates[i]
        for rate in rates[i + 1:]:
            if not attempt(rate):
                break
            best = rate
    else:
        for rate in reversed(rates[:i]):
            if attempt(rate):
                best = rate
                break
    if best is not None and best != rates[-1]:
        ceiling = rates[rates.index(best) + 1]
        while ceiling - best > REFINE_STEP_HZ:
            mid = best + (ceiling - best) // (2 * REFINE_STEP_HZ) * REFINE_STEP_HZ
            mid = max(mid, best + REFINE_STEP_HZ)
            if attempt(mid):
                best = mid
            else:
                ceiling = mid
    return {"max_rate_hz": best, "tried": [tried[r] for r in sorted(tried)]}


def loop_split(rep: dict[str, Any]) -> dict[str, float]:
    """Cycles per loop for each activity id (names of the issue 6 contract), plus sleep."""
    loops = max(1, int(rep["loops"]))
    out = {ACTIVITY_KEYS.get(int(k), f"id{k}"): round(v["cycles"] / loops, 1)
           for k, v in sorted(rep["activity"].items(), key=lambda kv: int(kv[0]))}
    out["sleep"] = round(rep["sleep_cycles"] / loops, 1)
    return out


def headline_figures(steps: dict[str, Any], run: LoopRun, flash: int,
                     ram: int) -> dict[str, Any]:
    """The `firmware` JSON's figures (docs/design.md §4) from the step bench and one loop run."""
    rep = run.report
    return {
        "fixed_step_cycles": steps["fixed"]["worst"],
        "float_step_cycles": steps["float"]["worst"],
        "fixed_over_float": round(steps["fixed"]["worst"] / steps["float"]["worst"], 4),
        # the filter start's one sum measurement, timed apart (docs/design.md §4.6)
        "release_step_cycles": steps.get("release_step_cycles"),
        "loop_rate_hz": round(run.loop_rate_hz, 2),
        "idle_fraction": round(rep["idle_fraction"], 4),
        "bus_occupancy": round(rep["bus"]["occupancy"], 4),
        "flash_bytes": flash,
        "ram_bytes": ram,
        "stack_peak_bytes": rep["stack_peak_bytes"],
        "ram_plus_stack_bytes": ram + rep["stack_peak_bytes"],
    }


def loop_figures(run: LoopRun, rig: str, ok: bool, why: str) -> dict[str, Any]:
    """What the loop run's window said, for the JSON's `loop`."""
    rep = run.report
    return {"rig": rig, "rate_hz": run.rate_hz, "window_s": rep["seconds"],
            "frames": run.frames, "frames_lost": run.frames_lost,
            "stale_frames": run.stale_frames, "overruns": run.overruns,
            "uart_drops": run.uart_drops, "sustained": ok, "why": why,
            "bus": rep["bus"], "uart": rep["uart"]}


def run_firmware_bench(build_dir: Path | None = None, *, build: bool = True,
                       window_s: float = DEFAULT_WINDOW_S, sweep: bool = True,
                       sections: bool = False,
                       progress: Progress = lambda _: None) -> dict[str, Any]:
    """The JSON document of docs/design.md §4 (`firmware`) plus the details behind each figure."""
    progress("building")
    art = locate(build_dir, build=build)
    with tempfile.TemporaryDirectory(prefix="jointangle-bench-fw-") as d:
        work = Path(d)
        progress("filter steps: every step of every scenario (avr_cycles)")
        steps = step_cycles(art, work)
        progress(f"loop: four ADXL345 at {DEFAULT_RATE_HZ} Hz, {window_s:g} s simulated")
        run = run_loop(art, "adxl345", DEFAULT_RATE_HZ, window_s, work)
        flash, ram = image_size(art.image)
        rep = run.report
        ok, why = run.sustained()
        doc: dict[str, Any] = {
            **headline_figures(steps, run, flash, ram),
            "loop_cycles_per_loop": loop_split(rep),
            "loop": loop_figures(run, "four ADXL345 behind a TCA9548A (gravity rig)", ok, why),
            "steps": steps,
            "image": str(art.image),
            "notes": ["bus occupancy at a real 400 kHz from the bytes on the bus (9 SCL periods "
                      "per byte, 1 per START/Sr/STOP); the board also times every TWI byte at "
                      "400 kHz (simavr 1.6 alone runs the bus at ~1 MHz whatever TWBR says)",
                      NO_STRETCH_NOTE],
        }
        if sections:
            progress("filter step by section: every step of every scenario (avr_cycles)")
            doc["step_sections"] = step_sections(art, work)
        if sweep:
            doc["max_rate_hz"] = {
                model: max_sustained_rate(art, model, min(window_s, 1.0), work, progress)
                for model in ("adxl345", "bno055")}
            # ADXL345 arrays of 2, 3 and 4 sensors a link: the filter step and the loop rate.
            by_n: dict[str, Any] = {"2": {
                **steps["by_sensors_per_link"].get("2", {}),
                "max_rate_hz": doc["max_rate_hz"]["adxl345"]["max_rate_hz"]}}
            for n in (3, 4):
                r = max_sustained_rate(art, "adxl345", min(window_s, 1.0), work, progress,
                                       per_link=n)
                by_n[str(n)] = {**steps["by_sensors_per_link"].get(str(n), {}),
                                "max_rate_hz": r["max_rate_hz"], "tried": r["tried"]}
            doc["by_sensors_per_link"] = by_n
            # The rate a board can promise (issue 17): held with >= 20 % of the cycles asleep,
            # four ADXL345, for the full frame and for the lean one (--stream estimates).
            doc["max_rate_hz_at_20_percent_asleep"] = {
                stream: max_sustained_rate(art, "adxl345", min(window_s, 1.0), work, progress,
                                           stream=stream, min_asleep=0.2)["max_rate_hz"]
                for stream in ("full", "estimates")}
    return doc


def env_build_dir() -> Path | None:
    v = os.environ.get("JOINTANGLE_BUILD_DIR")
    return Path(v) if v else None
