"""Rig files: one TOML file describes a physical build (docs/design.md §4).

`load_rig` validates everything and raises `InputError` naming the file, the line and the field.
`dump_rig` writes a rig back out (used by `simulate --rig-out` and calibration).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import tomli_w

from jointangle.errors import InputError
from jointangle.sensors import SENSOR_MODELS, STANDARD_GRAVITY

LINK_NAMES = ("a", "b")
UTF8_BOM = "\ufeff"  # TOML allows none


@dataclass(frozen=True)
class SensorConfig:
    """One accelerometer on a link, as the rig file describes it."""

    model: str
    position: tuple[float, float]  # metres, link frame
    mux_channel: int
    address: int
    range_g: int
    rotation_deg: float = 0.0  # sensor frame about z relative to the link
    noise_density_ug: tuple[float, float, float] | None = None  # µg/√Hz per axis
    S: tuple[tuple[float, ...], ...] | None = None  # calibration a = S v + o
    offset: tuple[float, float, float] | None = None  # m/s²
    quantize: bool = True  # simulation only: round to the model's LSB
    sim_bias_mps2: tuple[float, float, float] | None = None  # simulation only
    sim_scale_error: tuple[float, float, float] | None = None  # simulation only, fraction
    # simulation only: the real sensor axes rotated from the nominal frame by this rotation
    # vector (degrees, about x, y, z), and cross-axis coupling [xy, xz, yx, yz, zx, zy]
    # (fraction of axis n read by axis m, Madgwick eq. 38's s_mn); see sim/sensor_model.py
    sim_misalignment_deg: tuple[float, float, float] | None = None
    sim_cross_axis: tuple[float, float, float, float, float, float] | None = None
    # simulation only, the rig as built (sim/as_built.py): the true position is `position` +
    # this (m), the true in-plane mounting `rotation_deg` + this (°), and the sample of row k is
    # taken this long after the row's time (s; a multiplexed loop reads sensors in turn)
    sim_position_offset_m: tuple[float, float] | None = None
    sim_rotation_offset_deg: float | None = None
    sim_read_skew_s: float | None = None
    # simulation only: the part's conversion clock (sim/sensor_timing.py `part_clock`): its
    # oscillator's frequency error (ppm, + = fast) and its grid's phase (a fraction of a period)
    sim_clock_ppm: float | None = None
    sim_clock_phase: float | None = None
    # when the loop samples this sensor, after the row's time (s): a multiplexed board reads
    # its sensors one after another at known bus times (docs/as-built.md); array filters model it
    read_delay_s: float = 0.0

    @property
    def density_ug(self) -> tuple[float, float, float]:
        """Noise density per axis: the rig file's figure, else the datasheet's."""
        if self.noise_density_ug is not None:
            return self.noise_density_ug
        return SENSOR_MODELS[self.model].noise_density_ug

    def lsb_mps2(self) -> float:
        return SENSOR_MODELS[self.model].lsb_mps2(self.range_g)


@dataclass(frozen=True)
class LinkConfig:
    joint: tuple[float, float]  # metres, link frame: the hinge point O
    sensors: tuple[SensorConfig, ...]
    sim_joint_offset_m: tuple[float, float] | None = None  # simulation only: true O − joint (m)

    def positions(self) -> np.ndarray:
        """Sensor positions as an (N, 2) array."""
        return np.array([s.position for s in self.sensors], dtype=float)


@dataclass(frozen=True)
class Rig:
    name: str
    sample_rate_hz: float
    links: dict[str, LinkConfig] = field(default_factory=dict)
    source: str | None = None
    # [joint] range_deg = [lo, hi]: the joint's range of motion in degrees (θ_ab), optional;
    # array-ekf-rom reads it (estimators/neighbours/constrained.py).
    joint_range_deg: tuple[float, float] | None = None

    @property
    def dt(self) -> float:
        return 1.0 / self.sample_rate_hz

    def sensor_count(self, link: str) -> int:
        return len(self.links[link].sensors)

    def all_sensors(self) -> list[tuple[str, int, SensorConfig]]:
        """(link, index, sensor) in file order, links a then b."""
        return [
            (name, i, s) for name in LINK_NAMES for i, s in enumerate(self.links[name].sensors)
        ]

    def read_delays(self) -> np.ndarray:
        """Every sensor's `read_delay_s` in file order, links a then b (s)."""
        return np.array([s.read_delay_s for _, _, s in self.all_sensors()], dtype=float)

    def noise_sigma_mps2(self, link: str) -> np.ndarray:
        """Per-sample noise σ on each sensor's x and y, shape (2N,): density·g·√(fs/2).

        This is the σ the pinned filters use for Q̂ (docs/design.md §3).
        """
        out = []
        for s in self.links[link].sensors:
            d = s.density_ug
            for axis in (0, 1):
                out.append(d[axis] * 1e-6 * STANDARD_GRAVITY * math.sqrt(self.sample_rate_hz / 2))
        return np.array(out)

    def with_sample_rate(self, rate_hz: float) -> Rig:
        return replace(self, sample_rate_hz=rate_hz)


# --------------------------------------------------------------------------------------------
# Loading


def _locate_line(text: str, table: str | None, key: str | None, index: int | None = None) -> int:
    """Best-effort line number (1-based) of `key` inside `[table]` / the index-th `[[table]]`."""
    lines = text.splitlines()
    start = 0
    if table is not None:
        header = re.compile(r"^\s*\[\[?\s*" + re.escape(table) + r"\s*\]\]?\s*(#.*)?$")
        seen = -1
        found = None
        for n, line in enumerate(lines):
            if header.match(line):
                seen += 1
                if index is None or seen == index:
                    found = n
                    break
        if found is None:
            return 1
        start = found
        if key is None:
            return start + 1
    if key is None:
        return 1
    key_re = re.compile(r"^\s*" + re.escape(key) + r"\s*=")
    for n in range(start + (1 if table is not None else 0), len(lines)):
        if table is not None and n > start and re.match(r"^\s*\[", lines[n]):
            break
        if key_re.match(lines[n]):
            return n + 1
    return start + 1


class _Reader:
    """Pulls typed fields out of a parsed TOML table, raising located errors."""

    def __init__(self, path: str, text: str) -> None:
        self.path = path
        self.text = text

    def fail(
        self, msg: str, field: str, table: str | None = None, key: str | None = None,
        index: int | None = None,
    ) -> InputError:
        line = _locate_line(self.text, table, key, index)
        return InputError(msg, path=self.path, line=line, field=field)

    def number(self, tbl: dict[str, Any], key: str, where: tuple[str, str | None, int | None],
               *, required: bool = True, default: float | None = None) -> float | None:
        fname, table, idx = where
        if key not in tbl:
            if required:
                raise self.fail("missing required field", f"{fname}{key}", table, None, idx)
            return default
        v = tbl[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.fail(f"expected a finite number, got {v!r}", f"{fname}{key}", table, key,
                            idx)
        self.plausible(key, [float(v)], where)
        return float(v)

    def plausible(self, key: str, values: list[float],
                   where: tuple[str, str | None, int | None]) -> None:
        """Refuse a value outside the field's physical range (PLAUSIBLE), naming both."""
        bounds = PLAUSIBLE.get(key)
        if bounds is None:
            return
        lo, hi, unit, why = bounds
        for x in values:
            if (not lo <= x <= hi or (key in _POSITIVE and x <= 0)
                    or (key in _BELOW_HI and x >= hi)):
                fname, table, idx = where
                low = "> 0" if key in _POSITIVE else f"{lo:g}"
                high = f"< {hi:g}" if key in _BELOW_HI else f"{hi:g}"
                shown = x if len(values) == 1 else values
                raise self.fail(f"{shown!r} is out of range: {key} must be within {low} .. "
                                f"{high} {unit} ({why})", f"{fname}{key}", table, key, idx)

    def vector(self, tbl: dict[str, Any], key: str, n: int,
               where: tuple[str, str | None, int | None], *, required: bool = True
               ) -> tuple[float, ...] | None:
        fname, table, idx = where
        if key not in tbl:
            if required:
                raise self.fail("missing required field", f"{fname}{key}", table, None, idx)
            return None
        v = tbl[key]
        if (not isinstance(v, list) or len(v) != n
                or any(isinstance(x, bool) or not isinstance(x, int | float) for x in v)
                or not all(math.isfinite(x) for x in v)):
            raise self.fail(f"expected a list of {n} finite numbers, got {v!r}",
                            f"{fname}{key}", table, key, idx)
        self.plausible(key, [float(x) for x in v], where)
        return tuple(float(x) for x in v)


# [joint] range_deg = [lo, hi] is read by array-ekf-rom (estimators/neighbours/constrained.py).
_TOP_KEYS = {"name", "sample_rate_hz", "links", "joint"}
_JOINT_KEYS = {"range_deg"}
_LINK_KEYS = {"joint", "sensors", "sim_joint_offset_m"}
MAX_S_CONDITION = 100.0  # a calibration maps the axes nearly one to one (S ≈ I, cond ≈ 1)

# Physical plausibility of every numeric field: (lo, hi, unit, why). A value outside is a typo
# or a damaged file (1e308 m passed and overflowed the filters); refused naming field and line.
PLAUSIBLE: Mapping[str, tuple[float, float, str, str]] = MappingProxyType({
    "sample_rate_hz": (0.0, 10_000.0, "Hz", "the boards sample at up to 1 kHz"),
    "position": (-10.0, 10.0, "m", "a sensor on a limb or a robot link"),
    "joint": (-10.0, 10.0, "m", "the hinge on the link"),
    "rotation_deg": (-360.0, 360.0, "°", "one turn either way"),
    "noise_density_ug": (0.0, 100_000.0, "µg/√Hz", "every sensor has noise; datasheets say "
                         "~20-1000"),
    "S": (-10.0, 10.0, "", "a calibration maps each axis nearly one to one"),
    "offset": (-1000.0, 1000.0, "m/s²", "±100 g"),
    "sim_bias_mps2": (-1000.0, 1000.0, "m/s²", "±100 g"),
    "sim_scale_error": (-1.0, 1.0, "", "a fraction of full scale"),
    "sim_misalignment_deg": (-360.0, 360.0, "°", "one turn either way"),
    "sim_cross_axis": (-1.0, 1.0, "", "a fraction of the other axis"),
    "sim_position_offset_m": (-1.0, 1.0, "m", "a build error, not another place"),
    "sim_joint_offset_m": (-1.0, 1.0, "m", "a build error, not another place"),
    "sim_rotation_offset_deg": (-360.0, 360.0, "°", "one turn either way"),
    "sim_read_skew_s": (-1.0, 1.0, "s", "a read within the loop's period"),
    "read_delay_s": (-1.0, 1.0, "s", "a read within the loop's period"),
    "sim_clock_ppm": (-99_999.0, 99_999.0, "ppm", "an oscillator within ±10 %"),
    "sim_clock_phase": (0.0, 1.0, "periods", "a fraction of one conversion period, 1 excluded"),
})
_POSITIVE = frozenset({"sample_rate_hz", "noise_density_ug"})  # lo excluded
_BELOW_HI = frozenset({"sim_clock_phase"})  # hi excluded

_SENSOR_KEYS = {
    "model", "position", "rotation_deg", "mux_channel", "address", "range_g",
    "noise_density_ug", "S", "offset", "quantize", "sim_bias_mps2", "sim_scale_error",
    "sim_misalignment_deg", "sim_cross_axis", "sim_position_offset_m", "sim_rotation_offset_deg",
    "sim_read_skew_s", "read_delay_s", "sim_clock_ppm", "sim_clock_phase",
}


def _parse_sensor(r: _Reader, tbl: object, link: str, idx: int) -> SensorConfig:
    table = f"links.{link}.sensors"
    fname = f"links.{link}.sensors[{idx}]."
    where = (fname, table, idx)
    if not isinstance(tbl, dict):
        # `sensors = [1, 2]` rather than [[links.a.sensors]] tables: name the `sensors =` line.
        raise r.fail(f"expected a table (a [[{table}]] with model, position, ...), got "
                     f"{tbl!r}", fname.rstrip("."), f"links.{link}", "sensors")
    for key in tbl:
        if key not in _SENSOR_KEYS:
            raise r.fail(f"unknown field (known: {', '.join(sorted(_SENSOR_KEYS))})",
                         fname + key, table, key, idx)
    if "model" not in tbl:
        raise r.fail("missing required field", fname + "model", table, None, idx)
    model = tbl["model"]
    if not isinstance(model, str) or model not in SENSOR_MODELS:
        raise r.fail(f"unknown sensor model {model!r} (expected one of "
                     f"{', '.join(SENSOR_MODELS)})", fname + "model", table, "model", idx)
    pos = r.vector(tbl, "position", 2, where)
    assert pos is not None
    rot = r.number(tbl, "rotation_deg", where, required=False, default=0.0)
    chan = r.number(tbl, "mux_channel", where, required=False, default=0.0)
    assert chan is not None
    if chan != int(chan) or not 0 <= chan <= 7:
        raise r.fail(f"mux_channel must be an integer 0-7, got {tbl.get('mux_channel')!r}",
                     fname + "mux_channel", table, "mux_channel", idx)
    addr = r.number(tbl, "address", where, required=False, default=0x53)
    assert addr is not None
    if addr != int(addr) or not 0x08 <= addr <= 0x77:
        raise r.fail(f"address must be a 7-bit I2C address 0x08-0x77, got {addr!r}",
                     fname + "address", table, "address", idx)
    spec = SENSOR_MODELS[model]
    rng = r.number(tbl, "range_g", where, required=False, default=float(spec.ranges_g[0]))
    assert rng is not None
    if rng not in spec.ranges_g:
        raise r.fail(f"range_g {rng:g} is not valid for {model} (valid: "
                     f"{', '.join(str(x) for x in spec.ranges_g)})",
                     fname + "range_g", table, "range_g", idx)
    density: tuple[float, float, float] | None = None
    if "noise_density_ug" in tbl:
        v = tbl["noise_density_ug"]
        if isinstance(v, int | float) and not isinstance(v, bool):
            density = (float(v), float(v), float(v))
        else:
            vec = r.vector(tbl, "noise_density_ug", 3, where)
            assert vec is not None
            density = (vec[0], vec[1], vec[2])
        if not all(math.isfinite(d) and d > 0 for d in density):
            raise r.fail(f"noise density must be a finite number > 0 µg/√Hz (every sensor has "
                         f"noise; the filters' Q̂ is built from it), got {v!r}",
                         fname + "noise_density_ug", table, "noise_density_ug", idx)
        r.plausible("noise_density_ug", list(density), where)
    S = None
    if "S" in tbl:
        v = tbl["S"]
        ok = isinstance(v, list) and len(v) == 3 and all(
            isinstance(row, list) and len(row) == 3
            and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                    for x in row)
            for row in v)
        if not ok:
            raise r.fail("S must be a 3×3 list of finite numbers", fname + "S", table, "S", idx)
        S = tuple(tuple(float(x) for x in row) for row in v)
        r.plausible("S", [x for row in S for x in row], where)
        sv = np.linalg.svd(np.array(S), compute_uv=False)
        if not sv[0] > 0:
            raise r.fail("S is all zeros: a calibration maps each axis nearly one to one "
                         "(S ≈ I)", fname + "S", table, "S", idx)
        if not sv[-1] * MAX_S_CONDITION >= sv[0]:
            cond = sv[0] / sv[-1] if sv[-1] > 0 else math.inf
            raise r.fail(f"S is singular or nearly so (condition number {cond:.3g}, above "
                         f"{MAX_S_CONDITION:g}): a calibration maps each axis nearly one to one "
                         "(S ≈ I)", fname + "S", table, "S", idx)
    off = r.vector(tbl, "offset", 3, where, required=False)
    quant = tbl.get("quantize", True)
    if not isinstance(quant, bool):
        raise r.fail("quantize must be true or false", fname + "quantize", table, "quantize", idx)
    bias = r.vector(tbl, "sim_bias_mps2", 3, where, required=False)
    scale = r.vector(tbl, "sim_scale_error", 3, where, required=False)
    misalign = r.vector(tbl, "sim_misalignment_deg", 3, where, required=False)
    cross = r.vector(tbl, "sim_cross_axis", 6, where, required=False)
    pos_off = r.vector(tbl, "sim_position_offset_m", 2, where, required=False)
    rot_off = r.number(tbl, "sim_rotation_offset_deg", where, required=False)
    skew = r.number(tbl, "sim_read_skew_s", where, required=False)
    delay = r.number(tbl, "read_delay_s", where, required=False)
    clock_ppm = r.number(tbl, "sim_clock_ppm", where, required=False)
    clock_phase = r.number(tbl, "sim_clock_phase", where, required=False)

    def as3(v: tuple[float, ...] | None) -> tuple[float, float, float] | None:
        return None if v is None else (v[0], v[1], v[2])

    return SensorConfig(
        model=model, position=(pos[0], pos[1]), mux_channel=int(chan), address=int(addr),
        range_g=int(rng), rotation_deg=rot or 0.0, noise_density_ug=density, S=S,
        offset=as3(off), read_delay_s=delay or 0.0, quantize=quant, sim_bias_mps2=as3(bias),
        sim_scale_error=as3(scale),
        sim_misalignment_deg=as3(misalign),
        sim_cross_axis=None if cross is None else (cross[0], cross[1], cross[2], cross[3],
                                                   cross[4], cross[5]),
        sim_position_offset_m=None if pos_off is None else (pos_off[0], pos_off[1]),
        sim_rotation_offset_deg=rot_off, sim_read_skew_s=skew,
        sim_clock_ppm=clock_ppm, sim_clock_phase=clock_phase,
    )


def parse_rig(text: str, path: str = "<rig>") -> Rig:
    """Parse and validate rig-file text."""
    if text.startswith(UTF8_BOM):
        raise InputError("starts with a byte order mark (UTF-8 BOM, bytes EF BB BF), which TOML "
                         "does not allow: save the file as UTF-8 without BOM", path=path, line=1)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+)", str(exc))
        raise InputError(f"not valid TOML: {exc}", path=path,
                         line=int(m.group(1)) if m else None) from None
    except RecursionError:
        raise InputError("nested too deeply to be a rig file (tables or arrays inside each other "
                         "hundreds of levels deep)", path=path) from None
    r = _Reader(path, text)
    for top in data:
        if top not in _TOP_KEYS:
            v = data[top]  # [top] or [[top]]: name its header line
            table = isinstance(v, dict) or (isinstance(v, list) and bool(v)
                                            and all(isinstance(x, dict) for x in v))
            raise r.fail(f"unknown field (known: {', '.join(sorted(_TOP_KEYS))})", top,
                         top if table else None, None if table else top)
    joint_tbl = data.get("joint", {})
    if not isinstance(joint_tbl, dict):
        raise r.fail("joint must be a table ([joint] range_deg = [lo, hi])", "joint", None,
                     "joint")
    for jk in joint_tbl:
        if jk not in _JOINT_KEYS:
            raise r.fail(f"unknown field (known: {', '.join(sorted(_JOINT_KEYS))})",
                         f"joint.{jk}", "joint", jk)
    rom = r.vector(joint_tbl, "range_deg", 2, ("joint.", "joint", None), required=False)
    if rom is not None and not (-180.0 <= rom[0] < rom[1] <= 180.0):
        raise r.fail(f"range_deg must be [lo, hi] degrees with -180 ≤ lo < hi ≤ 180, got "
                     f"{list(rom)}", "joint.range_deg", "joint", "range_deg")
    name = data.get("name", Path(path).stem)
    if not isinstance(name, str):
        raise r.fail("name must be a string", "name", None, "name")
    rate = r.number(data, "sample_rate_hz", ("", None, None))
    assert rate is not None
    if rate <= 0:
        raise r.fail("sample_rate_hz must be > 0", "sample_rate_hz", None, "sample_rate_hz")
    links_tbl = data.get("links")
    if not isinstance(links_tbl, dict):
        raise InputError("missing [links.a] and [links.b] tables", path=path, field="links")
    for ln in links_tbl:
        if ln not in LINK_NAMES:
            raise InputError(f"unknown link (a rig has links {' and '.join(LINK_NAMES)})",
                             path=path, line=_locate_line(text, f"links.{ln}", None),
                             field=f"links.{ln}")
    links: dict[str, LinkConfig] = {}
    for link in LINK_NAMES:
        ltbl = links_tbl.get(link)
        if not isinstance(ltbl, dict):
            raise InputError(f"missing table [links.{link}]", path=path, field=f"links.{link}")
        for lk in ltbl:
            if lk not in _LINK_KEYS:
                raise r.fail(f"unknown field (known: {', '.join(sorted(_LINK_KEYS))})",
                             f"links.{link}.{lk}", f"links.{link}", lk)
        joint = r.vector(ltbl, "joint", 2, (f"links.{link}.", f"links.{link}", None))
        assert joint is not None
        joint_off = r.vector(ltbl, "sim_joint_offset_m", 2,
                             (f"links.{link}.", f"links.{link}", None), required=False)
        sensors_raw = ltbl.get("sensors", [])
        if not isinstance(sensors_raw, list) or len(sensors_raw) < 2:
            n = len(sensors_raw) if isinstance(sensors_raw, list) else 0
            raise InputError(
                f"link {link} needs at least two sensors ([[links.{link}.sensors]]), found {n}",
                path=path, line=_locate_line(text, f"links.{link}", None),
                field=f"links.{link}.sensors")
        sensors = tuple(_parse_sensor(r, s, link, i) for i, s in enumerate(sensors_raw))
        links[link] = LinkConfig(
            joint=(joint[0], joint[1]), sensors=sensors,
            sim_joint_offset_m=None if joint_off is None else (joint_off[0], joint_off[1]))
    # The same (mux channel, address) twice would read one chip as two sensors.
    seen: dict[tuple[int, int], str] = {}
    for link, i, s in [(ln, i, s) for ln in LINK_NAMES for i, s in enumerate(links[ln].sensors)]:
        key = (s.mux_channel, s.address)
        here = f"links.{link}.sensors[{i}]"
        if key in seen:
            raise InputError(
                f"mux channel {s.mux_channel} address 0x{s.address:02X} is already used by "
                f"{seen[key]}", path=path,
                line=_locate_line(text, f"links.{link}.sensors", "address", i),
                field=here + ".address")
        seen[key] = here
    return Rig(name=name, sample_rate_hz=rate, links=links, source=path,
               joint_range_deg=None if rom is None else (rom[0], rom[1]))


# --------------------------------------------------------------------------------------------
# Writing


def _sensor_table(s: SensorConfig) -> dict[str, Any]:
    t: dict[str, Any] = {
        "model": s.model,
        "position": list(s.position),
        "rotation_deg": s.rotation_deg,
        "mux_channel": s.mux_channel,
        "address": s.address,
        "range_g": s.range_g,
    }
    if s.noise_density_ug is not None:
        t["noise_density_ug"] = list(s.noise_density_ug)
    if s.S is not None:
        t["S"] = [list(row) for row in s.S]
    if s.offset is not None:
        t["offset"] = list(s.offset)
    if s.read_delay_s:
        t["read_delay_s"] = s.read_delay_s
    if not s.quantize:
        t["quantize"] = False
    if s.sim_bias_mps2 is not None:
        t["sim_bias_mps2"] = list(s.sim_bias_mps2)
    if s.sim_scale_error is not None:
        t["sim_scale_error"] = list(s.sim_scale_error)
    if s.sim_misalignment_deg is not None:
        t["sim_misalignment_deg"] = list(s.sim_misalignment_deg)
    if s.sim_cross_axis is not None:
        t["sim_cross_axis"] = list(s.sim_cross_axis)
    if s.sim_position_offset_m is not None:
        t["sim_position_offset_m"] = list(s.sim_position_offset_m)
    if s.sim_rotation_offset_deg is not None:
        t["sim_rotation_offset_deg"] = s.sim_rotation_offset_deg
    if s.sim_read_skew_s is not None:
        t["sim_read_skew_s"] = s.sim_read_skew_s
    if s.sim_clock_ppm is not None:
        t["sim_clock_ppm"] = s.sim_clock_ppm
    if s.sim_clock_phase is not None:
        t["sim_clock_phase"] = s.sim_clock_phase
    return t


def _link_table(link: LinkConfig) -> dict[str, Any]:
    t: dict[str, Any] = {"joint": list(link.joint)}
    if link.sim_joint_offset_m is not None:
        t["sim_joint_offset_m"] = list(link.sim_joint_offset_m)
    t["sensors"] = [_sensor_table(s) for s in link.sensors]
    return t


def dump_rig(rig: Rig) -> str:
    """Rig as TOML text that `parse_rig` reads back to an equal rig."""
    doc: dict[str, Any] = {
        "name": rig.name,
        "sample_rate_hz": rig.sample_rate_hz,
        "links": {ln: _link_table(rig.links[ln]) for ln in LINK_NAMES},
    }
    if rig.joint_range_deg is not None:
        doc["joint"] = {"range_deg": list(rig.joint_range_deg)}
    return tomli_w.dumps(doc)


def sensor_labels(rig: Rig) -> Sequence[str]:
    """Column prefixes in CSV order: a.0, a.1, ..., b.0, ..."""
    return [f"{ln}.{i}" for ln, i, _ in rig.all_sensors()]
