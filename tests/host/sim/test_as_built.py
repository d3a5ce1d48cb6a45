"""The rig as built: simulation-only geometry errors reach the simulator, never the estimators."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from jointangle.errors import InputError
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.registry import get_estimator
from jointangle.rig import Rig, dump_rig, parse_rig
from jointangle.sim.as_built import (
    AS_BUILT_LEVELS,
    BOARD_SKEW_PER_SENSOR_S,
    as_built_rig,
    nominal_rig,
    only_sources,
    split_variant,
)
from jointangle.sim.scenarios import (
    as_built_names,
    get_scenario,
    gravity_rig,
    simulate,
    simulate_rig,
)


def _quiet(rig: Rig) -> Rig:
    """Noise-free (nearly), unquantised sensors: readings are the physics alone."""
    return replace(rig, links={ln: replace(link, sensors=tuple(
        replace(s, noise_density_ug=(1e-9, 1e-9, 1e-9), quantize=False) for s in link.sensors))
        for ln, link in rig.links.items()})


def test_round_trip_and_determinism() -> None:
    rig = as_built_rig(gravity_rig(100.0), seed=3)
    again = parse_rig(dump_rig(rig), "x.toml")
    assert again.links == rig.links
    assert as_built_rig(gravity_rig(100.0), seed=3) == rig
    assert as_built_rig(gravity_rig(100.0), seed=4) != rig
    # The nominal geometry is untouched; only sim_* fields carry the build. The board's read
    # times are no build error: the board knows them, so the rig says them (read_delay_s).
    nom = nominal_rig(rig)
    assert [s.read_delay_s for _, _, s in nom.all_sensors()] == pytest.approx(
        [k * BOARD_SKEW_PER_SENSOR_S for k in range(4)])
    assert only_sources(nom, []) == gravity_rig(100.0)
    e = AS_BUILT_LEVELS["as-built"]
    for k, (_, _, s) in enumerate(rig.all_sensors()):
        assert s.sim_position_offset_m is not None and s.sim_rotation_offset_deg is not None
        assert max(map(abs, s.sim_position_offset_m)) <= e.position_m
        assert abs(s.sim_rotation_offset_deg) <= e.mounting_deg
        assert s.sim_read_skew_s == pytest.approx(k * BOARD_SKEW_PER_SENSOR_S)


def test_one_error_source_at_a_time() -> None:
    rig = as_built_rig(gravity_rig(100.0), seed=5)
    fields = {"positions": "sim_position_offset_m", "mountings": "sim_rotation_offset_deg",
              "skew": "sim_read_skew_s"}
    for src in ("positions", "mountings", "joints", "skew"):  # (clocks: the test below)
        one = only_sources(rig, [src])
        for other, name in fields.items():
            values = [getattr(s, name) for _, _, s in one.all_sensors()]
            want = [getattr(s, name) for _, _, s in rig.all_sensors()]
            assert values == (want if other == src else [None] * 4)
        assert [s.read_delay_s for _, _, s in one.all_sensors()] == [
            s.read_delay_s if src == "skew" else 0.0 for _, _, s in rig.all_sensors()]
        joints = [one.links[ln].sim_joint_offset_m for ln in ("a", "b")]
        assert joints == ([rig.links[ln].sim_joint_offset_m for ln in ("a", "b")]
                          if src == "joints" else [None, None])
    assert only_sources(rig, ["positions", "mountings", "joints", "skew"]) == rig
    with pytest.raises(ValueError, match="unknown"):
        only_sources(rig, ["gravity"])


def test_bad_as_built_field_is_named() -> None:
    text = dump_rig(as_built_rig(gravity_rig(100.0), seed=0))
    bad = text.replace("sim_read_skew_s = 0.0", "sim_read_skew_s = 5.0", 1)
    with pytest.raises(InputError, match=r"links\.a\.sensors\[0\]\.sim_read_skew_s"):
        parse_rig(bad, "x.toml")
    bad = text.replace("sim_joint_offset_m = [", 'sim_joint_offset_m = ["x",', 1)
    with pytest.raises(InputError, match=r"links\.a\.sim_joint_offset_m"):
        parse_rig(bad, "x.toml")


def test_variant_names() -> None:
    assert split_variant("gravity-ramp-as-built-uncal") == ("gravity-ramp", "as-built-uncal")
    assert split_variant("gravity-ramp-as-built") == ("gravity-ramp", "as-built")
    assert "paper-table2-L10-as-built" in as_built_names()
    assert get_scenario("paper-table2-L10-as-built").name == "paper-table2-L10"
    with pytest.raises(InputError, match="unknown scenario"):
        get_scenario("nope-as-built")


def _readings(rig: Rig, name: str = "gravity-fast-periodic", seconds: float = 2.0
              ) -> np.ndarray:
    return simulate(name, seed=1, seconds=seconds, rig=rig).readings


def test_geometry_reaches_the_readings() -> None:
    base = _quiet(gravity_rig(100.0))
    ideal = _readings(base)
    # A mounting offset reads as that mounting would.
    turned = replace(base, links={**base.links, "b": replace(base.links["b"], sensors=(
        replace(base.links["b"].sensors[0], sim_rotation_offset_deg=1.5),
        base.links["b"].sensors[1]))})
    nominal_turned = replace(base, links={**base.links, "b": replace(base.links["b"], sensors=(
        replace(base.links["b"].sensors[0], rotation_deg=1.5), base.links["b"].sensors[1]))})
    np.testing.assert_allclose(_readings(turned), _readings(nominal_turned), atol=1e-12)
    assert np.max(np.abs(_readings(turned) - ideal)) > 0.1
    # A joint offset δ is, to the sensors, their common shift by −δ.
    d = (0.003, -0.002)
    lb = base.links["b"]
    moved_joint = replace(base, links={**base.links, "b": replace(lb, sim_joint_offset_m=d)})
    moved_sensors = replace(base, links={**base.links, "b": replace(lb, sensors=tuple(
        replace(s, sim_position_offset_m=(-d[0], -d[1])) for s in lb.sensors))})
    np.testing.assert_allclose(_readings(moved_joint), _readings(moved_sensors), atol=1e-12)
    assert np.max(np.abs(_readings(moved_joint) - ideal)) > 1e-3


def test_read_skew_samples_later() -> None:
    base = _quiet(gravity_rig(100.0))
    lb = base.links["b"]
    skewed = replace(base, links={**base.links, "b": replace(lb, sensors=(
        replace(lb.sensors[0], sim_read_skew_s=0.01), lb.sensors[1]))})
    ideal = _readings(base)
    late = _readings(skewed)
    np.testing.assert_allclose(late[:-1, 2], ideal[1:, 2], atol=1e-9)  # one period later
    np.testing.assert_allclose(late[:, 3], ideal[:, 3], atol=1e-12)  # the others unchanged


@pytest.mark.parametrize("name", ["ekf", "array-ekf"])
def test_estimators_ignore_the_build(name: str) -> None:
    sim = simulate("gravity-fast-periodic-as-built", seed=2, seconds=3.0)
    nominal = nominal_rig(sim.rig)
    acc = sensor_to_link(sim.rig, sim.readings)[None]
    assert np.array_equal(acc, sensor_to_link(nominal, sim.readings)[None])
    est = get_estimator(name)
    a = est.estimate(sim.rig, acc)
    b = est.estimate(nominal, acc)
    assert np.array_equal(a.theta, b.theta)
    # ... and the build does change what they see.
    ideal = simulate("gravity-fast-periodic", seed=2, seconds=3.0)
    assert np.max(np.abs(ideal.readings - sim.readings)) > 0.01


def test_bench_accuracy_as_built_json(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from jointangle.cli.main import main

    assert main(["bench", "accuracy", "--json", "--seeds", "1", "--jobs", "1", "--scenarios",
                 "gravity-slow-periodic", "--filters", "array-ekf", "--as-built"]) == 0
    doc = json.loads(capsys.readouterr().out)
    sc = doc["scenarios"][0]
    assert set(sc) >= {"name", "filters", "paper", "as_built"}  # design.md §4.6, plus a key
    ideal = sc["filters"]["array-ekf"]
    assert {"theta_rms_deg", "theta_rms_startup_deg", "theta_worst_seed_deg"} <= set(ideal)
    for level in AS_BUILT_LEVELS:
        f = sc["as_built"][level]["filters"]["array-ekf"]
        assert f["theta_ratio_to_ideal"] == pytest.approx(
            f["theta_rms_deg"] / ideal["theta_rms_deg"], rel=2e-3)
        assert f["theta_rms_deg"] > ideal["theta_rms_deg"]  # the build costs accuracy
    # Uncalibrated mountings cost more than calibrated ones.
    assert (sc["as_built"]["as-built-uncal"]["filters"]["array-ekf"]["theta_rms_deg"]
            > sc["as_built"]["as-built"]["filters"]["array-ekf"]["theta_rms_deg"])


def test_bench_accuracy_unknown_level_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    from jointangle.cli.main import main

    assert main(["bench", "accuracy", "--as-built", "as-drawn", "--seeds", "1"]) == 2
    err = capsys.readouterr().err
    assert "--as-built" in err and "as-drawn" in err and len(err.strip().splitlines()) == 1


def test_no_estimator_reads_a_simulation_field() -> None:
    from pathlib import Path

    import jointangle.estimators as est_pkg
    import jointangle.model as model

    root = Path(est_pkg.__file__).parent
    files = [*root.rglob("*.py"), Path(model.__file__)]
    offenders = [str(f) for f in files if ".sim_" in f.read_text(encoding="utf-8")]
    assert files and not offenders


def test_clocks_level_is_the_as_built_geometry_with_free_running_parts() -> None:
    rig = gravity_rig(100.0)
    plain = as_built_rig(rig, seed=7, level="as-built")
    clocked = as_built_rig(rig, seed=7, level="as-built-clocks")
    e = AS_BUILT_LEVELS["as-built-clocks"]
    assert e.clock_ppm is not None
    for (_, _, p), (_, _, c) in zip(plain.all_sensors(), clocked.all_sensors(), strict=True):
        # The same build: the clocks draw from their own stream.
        assert (c.sim_position_offset_m, c.sim_rotation_offset_deg, c.sim_read_skew_s) == (
            p.sim_position_offset_m, p.sim_rotation_offset_deg, p.sim_read_skew_s)
        assert c.sim_clock_ppm is not None and abs(c.sim_clock_ppm) <= e.clock_ppm
        assert c.sim_clock_phase is not None and 0.0 <= c.sim_clock_phase < 1.0
        # The board knows its ODR (200 Hz at 100 Hz): the sample is on average 2.5 ms older.
        assert c.read_delay_s == pytest.approx(p.read_delay_s - 2.5e-3)
        assert p.sim_clock_ppm is None and p.sim_clock_phase is None
    assert parse_rig(dump_rig(clocked), "x.toml").links == clocked.links
    # Without the clocks the known delays are the read skew's again, and vice versa.
    no_clocks = only_sources(clocked, ["positions", "mountings", "joints", "skew"])
    assert [s.read_delay_s for _, _, s in no_clocks.all_sensors()] == pytest.approx(
        [s.read_delay_s for _, _, s in plain.all_sensors()])
    clocks_only = only_sources(clocked, ["clocks"])
    assert [s.read_delay_s for _, _, s in clocks_only.all_sensors()] == pytest.approx(
        [-2.5e-3] * 4)
    assert all(s.sim_read_skew_s is None for _, _, s in clocks_only.all_sensors())


def test_a_clocked_part_gives_its_latest_conversion_before_the_read() -> None:
    base = _quiet(gravity_rig(100.0))
    lb = base.links["b"]
    # ODR 200 Hz (5 ms), 2 % fast, grid offset 0.3 periods: conversions at O + j·P.
    clocked = replace(base, links={**base.links, "b": replace(lb, sensors=(
        replace(lb.sensors[0], sim_clock_ppm=20_000.0, sim_clock_phase=0.3), lb.sensors[1]))})
    period = int(np.floor(5_000_000 / 1.02 + 0.5))
    offset = int(np.floor(0.3 * period + 0.5))
    t = np.arange(200) / 100.0
    j = np.floor((np.maximum(np.rint(t * 1e9), offset) - offset) / period)
    t_conv = (offset + j * period) * 1e-9
    after = t >= offset * 1e-9  # before its first conversion a read gets that one
    assert np.all(t_conv[after] <= t[after] + 1e-12)
    assert np.all(t[after] - t_conv[after] < period * 1e-9 + 1e-12)
    sim = simulate("gravity-fast-periodic", seed=1, seconds=2.0, rig=clocked)
    mech = get_scenario("gravity-fast-periodic").mechanism(t_conv)
    from jointangle.sim.mechanism import specific_force_link
    from jointangle.sim.sensor_model import link_to_sensor
    f = specific_force_link(mech, "b", base.links["b"].positions()[:1],
                            np.asarray(get_scenario("gravity-fast-periodic").gravity_world))
    want = link_to_sensor(lb.sensors[0].rotation_deg, f[:, 0, :])
    np.testing.assert_allclose(sim.readings[:, 2], want, atol=1e-6)
    assert np.max(np.abs(sim.readings[:, 2] - _readings(base)[:, 2])) > 0.05
    np.testing.assert_allclose(sim.readings[:, 3], _readings(base)[:, 3], atol=1e-12)


def test_a_clock_phase_of_one_period_is_refused_with_its_name() -> None:
    text = dump_rig(as_built_rig(gravity_rig(100.0), seed=0, level="as-built-clocks"))
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("sim_clock_phase"))
    lines[i] = "sim_clock_phase = 1.0"
    with pytest.raises(InputError, match=r"links\.a\.sensors\[0\]\.sim_clock_phase.*< 1"):
        parse_rig("\n".join(lines), "x.toml")
    lines[i] = "sim_clock_phase = 0.5"
    k = next(k for k, ln in enumerate(lines) if ln.startswith("sim_clock_ppm"))
    lines[k] = "sim_clock_ppm = 200000.0"
    with pytest.raises(InputError, match=r"links\.a\.sensors\[0\]\.sim_clock_ppm"):
        parse_rig("\n".join(lines), "x.toml")


def test_timing_needs_the_motion_at_any_time_and_names_its_field() -> None:
    sc = get_scenario("gravity-fast-periodic")
    base = gravity_rig(100.0)
    mech = sc.mechanism(np.arange(20) / 100.0)
    lb = base.links["b"]
    for fields, name in (({"sim_read_skew_s": 1e-3}, "sim_read_skew_s"),
                         ({"sim_clock_ppm": 100.0, "sim_clock_phase": 0.5}, "sim_clock_ppm")):
        rig = replace(base, links={**base.links, "b": replace(lb, sensors=(
            replace(lb.sensors[0], **fields), lb.sensors[1]))})
        with pytest.raises(InputError, match=rf"links\.b\.sensors\[0\]\.{name}"):
            simulate_rig(rig, mech, np.asarray(sc.gravity_world), seed=0)
        simulate_rig(rig, mech, np.asarray(sc.gravity_world), seed=0, mechanism_at=sc.mechanism)
