"""Shared fixtures for the host tests."""

from __future__ import annotations

from pathlib import Path

import pytest

EXAMPLE_RIG = """\
name = "bench-L30"
sample_rate_hz = 100

[links.a]
joint = [0.30, 0.0]
[[links.a.sensors]]
model = "adxl345"
position = [0.25, 0.0]
rotation_deg = 0.0
mux_channel = 0
address = 0x53
range_g = 2
noise_density_ug = 400
[[links.a.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 0
address = 0x1D
range_g = 2

[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 1
address = 0x53
range_g = 2
[[links.b.sensors]]
model = "adxl357"
position = [0.25, 0.01]
rotation_deg = 90.0
mux_channel = 1
address = 0x1D
range_g = 10
"""


@pytest.fixture
def example_rig_text() -> str:
    return EXAMPLE_RIG


@pytest.fixture
def example_rig_path(tmp_path: Path) -> Path:
    p = tmp_path / "rig.toml"
    p.write_text(EXAMPLE_RIG)
    return p
