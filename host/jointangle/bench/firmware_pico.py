"""`jointangle bench firmware --board pico`: the Raspberry Pi Pico (RP2040) figures, measured in
the rp2040js emulator (firmware/sim/pico_board/README.md).

- Step cycles: the cycle harness (`pico_cycles.mjs`, avr_cycles' JSON) runs `bench_filter.elf`
  built for the Pico on every step of every scenario's full run, fixed point and float (the
  emulator's core cycle estimates), as the Mega's bench does (`bench.firmware.step_cycles`).
- The loop: the real image on the Pico virtual board with four ADXL345 behind the TCA9548A at
  1000 Hz on the simulated motion, streaming to this host over its pty (`bench.firmware.run_loop`,
  the window opened by SIGUSR1 once the stream runs): loop rate (frames stamped in the window),
  time asleep (WFI), bus occupancy at the SCL rate the firmware programs, frames with a stale
  sample, overruns, UART drops and lost frames. The two ADXL345 of a link share its multiplexer
  channel (0x53 and 0x1D): with a channel each, a loop's four selects and four 6-byte reads take
  ~435 SCL periods, 1.09 ms at 400 kHz, and no 1 kHz loop fits on one bus; paired, 380.75 on
  average (two selects, one read back every fourth loop: 0.95 ms), which holds 1 kHz.
- The highest sustained loop rate with four ADXL345 (≥ 50 % asleep), paired and with a channel
  each, and flash and RAM (arm-none-eabi-size).
Nothing is cached: every figure comes from this run on the images as built now.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from jointangle.bench.firmware import (
    Artefacts,
    Progress,
    build_trees,
    headline_figures,
    loop_figures,
    max_sustained_rate,
    run_loop,
    step_cycles,
)
from jointangle.built import REPO_ROOT
from jointangle.errors import InputError

TARGETS = ("pico_images", "ja_pico_bootrom", "ja_sim_board")
HARNESS_DIR = REPO_ROOT / "firmware" / "sim" / "pico_board"
DEFAULT_RATE_HZ = 1000  # the figure: four ADXL345 at 1 kHz
MIN_ASLEEP = 0.5
SWEEP_RATES_HZ = (500, 750, 1000)  # up to the firmware's set_rate maximum


def locate(build_dir: Path | None = None, *, build: bool = True) -> Artefacts:
    """The Pico's artefacts in the build tree (brought up to date first unless build=False) and
    the emulator harness; errors name what is missing and how to get it."""
    trees = build_trees(build_dir)
    if not trees:
        raise InputError("no configured build tree: run `cmake -S . -B build/native` (then "
                         "this bench builds what it needs)", field="--build-dir")
    tree = trees[0]
    if shutil.which("node") is None:
        raise InputError("the Pico bench needs Node.js (>= 18): `bash scripts/setup.sh` "
                         "installs it", field="node")
    if not (HARNESS_DIR / "node_modules" / "rp2040js").is_dir():
        raise InputError(f"the npm packages of {HARNESS_DIR} are not installed: `bash "
                         "scripts/setup.sh` installs them", field="node")
    if build:
        res = subprocess.run(["cmake", "--build", str(tree), "--target", *TARGETS],
                             capture_output=True, text=True, check=False)
        if res.returncode != 0:
            tail = (res.stdout + res.stderr).strip().splitlines()[-3:]
            raise InputError(f"building {' '.join(TARGETS)} in {tree} failed: "
                             + " | ".join(t.strip()[:160] for t in tail), field="--build-dir")
    sim = tree / "firmware" / "sim"
    paths = {"bench_filter": (tree / "pico" / "bench_filter.elf", "pico_images"),
             "image": (tree / "pico" / "jointangle_pico.elf", "pico_images"),
             "bootrom": (sim / "pico_bootrom.bin", "ja_pico_bootrom"),
             "board_lib": (sim / "libja_sim_board.so", "ja_sim_board")}
    for path, target in paths.values():
        if not path.is_file():
            raise InputError(f"{path.name} is not built in {tree}: run `cmake --build {tree} "
                             f"--target {target}`", field="--build-dir")
    return Artefacts(tree=tree, avr_cycles=HARNESS_DIR / "pico_cycles.mjs",
                     bench_filter=paths["bench_filter"][0],
                     board=HARNESS_DIR / "pico_board.mjs", image=paths["image"][0],
                     board_args=("--bootrom", str(paths["bootrom"][0]),
                                 "--board-lib", str(paths["board_lib"][0])))


def image_size(image: Path) -> tuple[int, int]:
    """(flash, static RAM) bytes: text + data, data + bss (arm-none-eabi-size, Berkeley)."""
    tool = shutil.which("arm-none-eabi-size")
    if tool is None:
        raise InputError("arm-none-eabi-size is not installed (binutils-arm-none-eabi; "
                         "scripts/setup.sh)", field="arm-none-eabi-size")
    out = subprocess.run([tool, str(image)], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    try:
        text, data, bss = (int(v) for v in out[1].split()[:3])
    except (IndexError, ValueError) as e:
        raise InputError(f"cannot read arm-none-eabi-size's output: {out!r}", path=image) from e
    return text + data, data + bss


def run_pico_bench(build_dir: Path | None = None, *, build: bool = True, window_s: float = 1.0,
                   sweep: bool = True, progress: Progress = lambda _: None) -> dict[str, Any]:
    """The `firmware` JSON document of docs/design.md §4 for the Pico, plus the details."""
    progress("building")
    art = locate(build_dir, build=build)
    with tempfile.TemporaryDirectory(prefix="jointangle-bench-pico-") as d:
        work = Path(d)
        progress("filter steps: every step of every scenario (pico_cycles.mjs)")
        steps = step_cycles(art, work)
        progress(f"loop: four ADXL345 at {DEFAULT_RATE_HZ} Hz, {window_s:g} s simulated")
        run = run_loop(art, "adxl345", DEFAULT_RATE_HZ, window_s, work, channel_per_link=True)
        flash, ram = image_size(art.image)
        rep = run.report
        ok, why = run.sustained(MIN_ASLEEP)
        doc: dict[str, Any] = {
            "board": "pico",
            **headline_figures(steps, run, flash, ram),
            "clk_sys_hz": rep["frequency_hz"],
            "loop": {**loop_figures(run, "four ADXL345 behind a TCA9548A, a channel per link "
                                    "(0x53, 0x1D)", ok, why),
                     "busy_cycles": rep["busy_cycles"]},
            "steps": steps,
            "image": str(art.image),
            "notes": ["cycles are rp2040js's core cycle estimates (flash reads as if the XIP "
                      "cache always hit); time asleep is time in WFI",
                      "bus occupancy at the SCL rate the firmware programs (DW_apb_i2c counts "
                      "at clk_sys): 9 SCL periods per byte, 1 per START/Sr/STOP"],
        }
        if sweep:
            doc["max_rate_hz_at_50_percent_asleep"] = {
                layout: max_sustained_rate(
                    art, "adxl345", min(window_s, 1.0), work, progress, rates=SWEEP_RATES_HZ,
                    start_hz=start, min_asleep=MIN_ASLEEP, channel_per_link=paired)
                for layout, paired, start in (("channel_per_link", True, DEFAULT_RATE_HZ),
                                              ("channel_per_sensor", False, 750))}
    return doc
