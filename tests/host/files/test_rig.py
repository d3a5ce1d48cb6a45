"""Rig files: the docs/design.md §4.1 example loads; every kind of mistake is named with file,
line, field."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointangle.errors import InputError
from jointangle.io.rig_file import load_rig
from jointangle.rig import dump_rig, parse_rig


def test_example_rig_loads(example_rig_path: Path) -> None:
    rig = load_rig(example_rig_path)
    assert rig.name == "bench-L30"
    assert rig.sample_rate_hz == 100
    assert rig.links["a"].joint == (0.30, 0.0)
    assert [s.address for _, _, s in rig.all_sensors()] == [0x53, 0x1D, 0x53, 0x1D]
    assert rig.links["a"].sensors[0].density_ug == (400.0, 400.0, 400.0)
    # No density given: the datasheet's (ADXL345 x/y 290, z 430 µg/√Hz).
    assert rig.links["a"].sensors[1].density_ug == (290.0, 290.0, 430.0)
    assert rig.links["b"].sensors[1].rotation_deg == 90.0


def test_round_trip(example_rig_text: str) -> None:
    rig = parse_rig(example_rig_text, "x.toml")
    again = parse_rig(dump_rig(rig), "x.toml")
    assert again.links == rig.links
    assert again.sample_rate_hz == rig.sample_rate_hz


def _broken(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("old", "new", "line", "field"),
    [
        ('model = "adxl345"', 'model = "mpu6050"', 7, "links.a.sensors[0].model"),
        ("range_g = 2\nnoise", "range_g = 3\nnoise", 12, "links.a.sensors[0].range_g"),
        ("position = [0.05, 0.0]\nmux_channel = 0", "position = [0.05]\nmux_channel = 0", 16,
         "links.a.sensors[1].position"),
        ("mux_channel = 1\naddress = 0x1D", "mux_channel = 9\naddress = 0x1D", 33,
         "links.b.sensors[1].mux_channel"),
        ("sample_rate_hz = 100", 'sample_rate_hz = "fast"', 2, "sample_rate_hz"),
        ("rotation_deg = 90.0", "rotation_degs = 90.0", 32, "links.b.sensors[1].rotation_degs"),
    ],
)
def test_bad_field_is_named(example_rig_text: str, tmp_path: Path, old: str, new: str,
                            line: int, field: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(_broken(example_rig_text, old, new))
    with pytest.raises(InputError) as exc:
        load_rig(p)
    assert exc.value.field == field
    assert exc.value.line == line
    assert str(p) in str(exc.value)


def test_one_sensor_link_is_refused(example_rig_text: str) -> None:
    head, _, _ = example_rig_text.partition("[[links.b.sensors]]\nmodel = \"adxl357\"")
    with pytest.raises(InputError, match="at least two sensors") as exc:
        parse_rig(head, "r.toml")
    assert exc.value.field == "links.b.sensors"


def test_duplicate_bus_address_is_refused(example_rig_text: str) -> None:
    text = _broken(example_rig_text, "mux_channel = 1\naddress = 0x53",
                   "mux_channel = 0\naddress = 0x53")
    with pytest.raises(InputError, match=r"already used by links\.a\.sensors\[0\]"):
        parse_rig(text, "r.toml")


def test_invalid_toml_names_the_line() -> None:
    with pytest.raises(InputError) as exc:
        parse_rig('name = "x"\nsample_rate_hz = = 3\n', "r.toml")
    assert exc.value.line == 2


@pytest.mark.parametrize(
    ("old", "new", "line", "field", "reason"),
    [
        ("range_g = 2\nnoise_density_ug = 400", "range_g = 2\nnoise_density_ug = 0", 13,
         "links.a.sensors[0].noise_density_ug", "> 0"),
        ("range_g = 2\nnoise_density_ug = 400", "range_g = 2\nnoise_density_ug = -5", 13,
         "links.a.sensors[0].noise_density_ug", "> 0"),
        ("range_g = 2\nnoise_density_ug = 400", "range_g = 2\nnoise_density_ug = nan", 13,
         "links.a.sensors[0].noise_density_ug", "> 0"),
        ("range_g = 2\nnoise_density_ug = 400",
         "range_g = 2\nnoise_density_ug = [400, 0, 400]", 13,
         "links.a.sensors[0].noise_density_ug", "> 0"),
        ("range_g = 2\nnoise_density_ug = 400",
         "range_g = 2\nnoise_density_ug = 400\nS = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]", 14,
         "links.a.sensors[0].S", "all zeros"),
        ("range_g = 2\nnoise_density_ug = 400",
         "range_g = 2\nnoise_density_ug = 400\nS = [[1, 0, 0], [1, 0, 0], [0, 0, 1]]", 14,
         "links.a.sensors[0].S", "singular"),
        ("range_g = 2\nnoise_density_ug = 400",
         "range_g = 2\nnoise_density_ug = 400\nS = [[1, 0, 0], [0, 1e-4, 0], [0, 0, 1]]", 14,
         "links.a.sensors[0].S", "singular"),
        ("range_g = 2\nnoise_density_ug = 400",
         "range_g = 2\nnoise_density_ug = 400\nS = [[1, 0, 0], [0, nan, 0], [0, 0, 1]]", 14,
         "links.a.sensors[0].S", "finite"),
        ("sample_rate_hz = 100", "sample_rate_hz = 100\nsample_rate = 200", 3,
         "sample_rate", "unknown field"),
        ("[links.b]\njoint", "[links.c]\njoint = [0.0, 0.0]\n\n[links.b]\njoint", 21,
         "links.c", "unknown link"),
        ("[links.b]\njoint = [0.0, 0.0]", "[links.b]\njoint = [0.0, 0.0]\nlength = 0.3", 23,
         "links.b.length", "unknown field"),
        ("range_g = 10\n", 'range_g = 10\n\n[meta]\nowner = "lab"\n', 37, "meta",
         "unknown field"),
        ("range_g = 10\n", "range_g = 10\n\n[joint]\nrange_deg = [0, 90]\nrange = 3\n", 39,
         "joint.range", "unknown field"),
    ],
)
def test_implausible_rig_is_refused(example_rig_text: str, tmp_path: Path, old: str, new: str,
                                    line: int, field: str, reason: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(_broken(example_rig_text, old, new))
    with pytest.raises(InputError, match=reason) as exc:
        load_rig(p)
    assert (exc.value.field, exc.value.line) == (field, line)
    assert str(p) in str(exc.value)


def test_a_calibrated_rig_still_loads(example_rig_text: str) -> None:
    text = _broken(example_rig_text, "range_g = 2\nnoise_density_ug = 400",
                   "range_g = 2\nnoise_density_ug = [310.5, 290, 455]\n"
                   "S = [[1.02, 0.01, -0.03], [0.0, 0.97, 0.02], [0.05, 0.0, 1.01]]\n"
                   "offset = [0.1, -0.2, 0.3]")
    s = parse_rig(text, "r.toml").links["a"].sensors[0]
    assert s.S is not None and s.S[0][0] == 1.02 and s.noise_density_ug == (310.5, 290, 455)


def test_the_joint_range_survives_writing_a_rig(tmp_path: Path) -> None:
    # [joint] range_deg is part of the Rig: dump_rig/write_rig keep it (calibrate writes its
    # rig through them; before, the range lived only in the source file and a rewritten rig
    # lost it).
    import dataclasses

    from jointangle.sim.scenarios import get_scenario

    rig = dataclasses.replace(get_scenario("gravity-slow-periodic").rig(100.0),
                              joint_range_deg=(-10.0, 95.5))
    back = parse_rig(dump_rig(rig))
    assert back.joint_range_deg == (-10.0, 95.5)
    path = tmp_path / "rig.toml"
    path.write_text(dump_rig(dataclasses.replace(rig, joint_range_deg=None)))
    assert "joint]" not in path.read_text() and load_rig(path).joint_range_deg is None
