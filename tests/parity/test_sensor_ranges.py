"""The firmware core's Q formats hold for every supported sensor at 100–1000 Hz (FILTER.md,
"Sensors and rates covered"): each scenario's rig with all four sensors replaced by one model at
its datasheet noise runs through the fixed-point core without a saturation and within the
docs/design.md §5 parity bounds against `mirror`. ADXL357 at 100 Hz is the tightest case (Q̂ =
3.1·10⁻⁵ per reading, D ≈ 6·10⁻⁵, 1/D ≈ 1.6·10⁴): it saturated 1/D in the former Q11.20."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from jointangle.bench.parity import (
    MAX_DOMEGA_DPS,
    MAX_DTHETA_DEG,
    STARTUP_MAX_DTHETA_DEG,
    general_rig,
    parity,
)
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.mirror import MirrorSettings
from jointangle.rig import Rig
from jointangle.sim.scenarios import get_scenario, simulate

RANGE_G = {"adxl345": 2, "adxl357": 10, "bno055": 2}


def _rig_with(scenario: str, model: str, rate_hz: float) -> Rig:
    base = get_scenario(scenario).rig(rate_hz)
    links = {name: replace(link, sensors=tuple(
        replace(s, model=model, range_g=RANGE_G[model], noise_density_ug=None)
        for s in link.sensors)) for name, link in base.links.items()}
    return replace(base, links=links)


@pytest.mark.parametrize("rate_hz", [100.0, 1000.0])
@pytest.mark.parametrize("model", ["adxl345", "adxl357", "bno055"])
@pytest.mark.parametrize("scenario", ["paper-table2-L30", "gravity-fast-periodic"])
def test_no_saturation_for_every_sensor(scenario: str, model: str, rate_hz: float) -> None:
    rig = _rig_with(scenario, model, rate_hz)
    sim = simulate(scenario, seed=1, rate_hz=rate_hz, seconds=4.0, rig=rig)
    acc = sensor_to_link(rig, sim.readings)[None]
    p = parity(rig, acc, sim.t)
    assert p.saturations == 0
    assert p.skipped_updates == 0
    assert p.max_abs_dtheta_deg <= MAX_DTHETA_DEG
    assert p.max_abs_domega_dps <= MAX_DOMEGA_DPS
    assert p.startup_max_abs_dtheta_deg <= STARTUP_MAX_DTHETA_DEG
    assert np.isfinite(p.rms_dtheta_deg)


@pytest.mark.parametrize("scenario", ["paper-table2-L20", "gravity-ramp"])
def test_general_geometry_parity(scenario: str) -> None:
    """Off-axis sensors and unequal x/y noise (`general_rig`, the AVR bench's second rig set):
    no zero entries in G, F, M_b01, c_b1, R₃₄, so none of the filter's sparse shortcuts apply;
    the core still matches `mirror` without saturation."""
    rig = general_rig(get_scenario(scenario).rig(100.0))
    sim = simulate(scenario, seed=2, seconds=6.0, rig=rig)
    cfg = MirrorSettings.from_rig(rig)
    assert abs(cfg.m_b[0, 1]) > 0.0 and abs(cfg.mb_dif) > 0.0 and abs(cfg.c_b[1]) > 0.0
    p = parity(rig, sensor_to_link(rig, sim.readings)[None], sim.t)
    assert p.saturations == 0
    assert p.skipped_updates == 0
    assert p.within_targets()
