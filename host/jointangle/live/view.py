"""The terminal readout of `jointangle live` (rich), sized for an 80×24 terminal."""

from __future__ import annotations

import time
from collections.abc import Sequence

from rich.console import Group
from rich.panel import Panel
from rich.text import Text

from jointangle.device.describe import FAULT_NAMES as FAULTS
from jointangle.device.describe import eeprom_warning, enum_name, flag_names, sustainable_rate_hz
from jointangle.live.host_filter import HostFilter
from jointangle.live.session import LiveState
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import text_of

TRACE_ROWS = 6
TRACE_WIDTH = 64
BLOCKS = " ▁▂▃▄▅▆▇█"
STALE_STATUS_S = 2.5  # status comes every 1 s while streaming (live's status_interval_ms)
LOOP_RATE_SHORT = 0.98  # a board loop below this fraction of its configured rate is warned of


def trace_lines(values: Sequence[float], width: int = TRACE_WIDTH,
                rows: int = TRACE_ROWS) -> tuple[list[str], float, float]:
    """A block chart of `values` (oldest left), `rows` lines of `width` cells; (lines, lo, hi)."""
    if not values:
        return [" " * width] * rows, 0.0, 0.0
    n = len(values)
    cols = [values[min(n - 1, int(i * n / width))] for i in range(min(width, n))]
    lo, hi = min(cols), max(cols)
    if hi - lo < 1.0:  # at least a 1° span so noise does not fill the chart
        mid = (hi + lo) / 2
        lo, hi = mid - 0.5, mid + 0.5
    levels = [(v - lo) / (hi - lo) * rows * 8 for v in cols]
    lines = []
    for r in range(rows - 1, -1, -1):
        line = ""
        for lv in levels:
            cell = min(8, max(0, round(lv - r * 8)))
            line += BLOCKS[cell]
        lines.append(line.ljust(width))
    return lines, lo, hi


def host_line(host: HostFilter | None, word: str | None) -> Text:
    """The host filter's θ beside the board's, with its lag, or why there is none."""
    if host is None:
        return Text(word or "host filter off", style="dim")
    h = host.latest
    line = Text()
    line.append(f"{host.name:<9} ", style="bold")
    if host.off is not None:
        line.append("switched off: cannot keep up", style="bold yellow")
        return line
    if h is None:
        line.append(host.note or f"waiting for {host.lag_ms:g} ms of samples…", style="dim")
        return line
    line.append(f"θ {h.theta_deg:9.3f}°", style="bold magenta")
    omega = ("" if h.omega_a_dps != h.omega_a_dps else  # (NaN: no ω, e.g. analytical)
             f"  ω_a {h.omega_a_dps:7.1f}  ω_b {h.omega_b_dps:7.1f}")
    line.append(f"{omega}  {host.lag_ms:g} ms behind · CPU {host.window_load:.0%}")
    if host.note:
        line.append(f"  {host.note}", style="yellow")
    return line


def render(state: LiveState, *, port: str, recording: str | None = None,
           rec_seconds: float = 0.0, stats: dict[str, int] | None = None,
           interactive: bool = True, message: str | None = None,
           host: HostFilter | None = None, host_word: str | None = None) -> Panel:
    stats = stats or {}
    h = state.hello
    title = (f"jointangle live · {port} · {enum_name(msgs.Board, h.board)} fw "
             f"{h.firmware_major}.{h.firmware_minor}.{h.firmware_patch} "
             f"{text_of(h.build)}")
    parts: list[Text] = []
    e = state.latest
    if e is None:
        parts.append(Text("waiting for estimates…", style="dim"))
    else:
        health = flag_names(msgs.FilterHealth, e.health)
        line = Text()
        line.append("θ ", style="bold")
        line.append(f"{e.theta_deg:9.3f}°", style="bold cyan")
        line.append(f"   ω_a {e.omega_a_dps:8.2f} °/s   ω_b {e.omega_b_dps:8.2f} °/s")
        parts.append(line)
        ok = "running" in health
        parts.append(Text(f"filter: {', '.join(health) or 'not running'}"
                          + ("" if ok else "  (θ and ω mean nothing)"),
                          style="" if ok else "bold red"))
    parts.append(host_line(host, host_word))
    lines, lo, hi = trace_lines([v for _, v in state.trace])
    for i, ln in enumerate(lines):
        label = f"{hi:7.1f}°" if i == 0 else f"{lo:7.1f}°" if i == len(lines) - 1 else ""
        parts.append(Text(f"{label:>8} ▕{ln}", style="green"))
    lost = stats.get("frames_lost", 0)
    frames = stats.get("frames", state.frames)
    loss = 100.0 * lost / (frames + lost) if frames + lost else 0.0
    st = state.status
    drops = "?" if st is None else str(st.uart_drops)
    parts.append(Text(f"rate {state.sample_rate:6.1f} Hz  frames {frames}  lost {lost} "
                      f"({loss:.2f} %)  crc {stats.get('crc_errors', 0)}  UART drops {drops}",
                      style="red" if lost or stats.get("crc_errors") else ""))
    link = [f"{stats[k]} {name}" for k, name in (
        ("duplicates", "duplicated"), ("out_of_order", "late"), ("stale", "stale"),
        ("version_errors", "other-version"), ("unknown_messages", "unknown"),
        ("segments", "segments")) if stats.get(k, 0) > (1 if k == "segments" else 0)]
    if link:  # what the link did besides losing frames (issue 16): shown only when it did
        parts.append(Text("link: " + ", ".join(link), style="yellow"))
    if st is not None and 0 < st.loop_rate_hz < LOOP_RATE_SHORT * state.rate_hz:
        # Each step predicts over the periods it missed (APP.md "Timing"): the estimates keep
        # time, but come less often than configured; a lower rate_hz gives a steady one.
        fits = sustainable_rate_hz(st)
        advice = f"lower rate_hz to ≤ {fits} Hz" if fits else "lower rate_hz"
        parts.append(Text(f"⚠ board loop {st.loop_rate_hz} of {state.rate_hz:.0f} Hz: "
                          f"{st.loop_overruns} periods missed; {advice}", style="bold yellow"))
    age = state.status_age_s
    if age is not None and age > STALE_STATUS_S:
        parts.append(Text(f"⚠ no status frame for {age:.0f} s: the board's counters above are "
                          "old", style="bold red"))
    d = state.divergence
    if state.rig is None:
        parts.append(Text("firmware − mirror: needs the rig (--rig)", style="dim"))
    elif d is None:
        why = state.run.broken if state.run is not None and state.run.broken else None
        wait = "waiting for a filter start… (live --restart-filter starts one)"
        parts.append(Text("firmware − mirror: " + (f"cannot follow ({why})" if why else wait),
                          style="dim"))
    else:
        age = time.monotonic() - d.at
        run = state.run
        tail = f"; stopped: {run.broken}" if run is not None and run.broken else ""
        parts.append(Text(f"firmware − mirror: max |Δθ| {d.max_abs_deg:.4f}°  rms "
                          f"{d.rms_deg:.4f}°  over {d.frames} frames ({age:.0f} s ago){tail}"))
    sens = Text("sensors:")
    per_link = {0: 0, 1: 0}
    for hs, inv in zip(state.sensors, h.sensors, strict=False):
        name = f"{'ab'[inv.link & 1]}{per_link[inv.link & 1]}"
        per_link[inv.link & 1] += 1
        bad = [f for f in flag_names(msgs.SensorStatus, hs.status) if f in FAULTS]
        sens.append(f" {name} ")
        sens.append(",".join(bad) if bad else "ok", style="bold red" if bad else "green")
    parts.append(sens)
    eeprom = h.eeprom if state.status is None else state.status.eeprom
    if eeprom_warning(eeprom):
        parts.append(Text(f"⚠ EEPROM {enum_name(msgs.EepromState, eeprom)}: the board runs on "
                          "factory defaults", style="bold yellow"))
    if state.observable is False:
        parts.append(Text("⚠ θ not observable: gravity out of the plane, too little motion — "
                          "a guess", style="bold yellow"))
    if message:
        parts.append(Text(message, style="yellow"))
    if state.last_log:
        parts.append(Text(f"device {state.last_log}"[:76], style="dim"))
    keys = ("r start/stop recording · q quit" if interactive else "non-interactive")
    rec = (f"REC {recording} {rec_seconds:.0f} s" if recording else "not recording")
    parts.append(Text(f"{rec} · {keys}", style="bold red" if recording else "dim"))
    return Panel(Group(*parts), title=title[:70], title_align="left", width=80)
