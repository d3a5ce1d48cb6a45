"""Placement design: the closed-form noise gain κ, the bounds against simulation, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.design import (
    build_rig,
    crb0_theta,
    kappa,
    pcrb_theta,
    reference_motion,
    simulate_errors,
    spread,
    steady_rms,
)


@pytest.mark.parametrize(("l_", "d_"), [(0.1, 0.1), (0.2, 0.05), (0.05, 0.1)])
def test_kappa_closed_form_for_two_sensors(l_: float, d_: float) -> None:
    """κ = 1/2 + (l/d)²/2 for two sensors with mean l/2 from the joint, d apart."""
    rig = build_rig(0.3, 0.6, spread(l_, d_, 2), spread(l_, d_, 2), noise_ug=400,
                    quantize=False)
    for link in ("a", "b"):
        assert kappa(rig, link) == pytest.approx(0.5 + 0.5 * (l_ / d_) ** 2, rel=1e-12)


def test_bounds_predict_simulation_and_order_placements() -> None:
    L = 0.2
    mot = reference_motion("paper-table2-L20", L, 2 * L, seconds=15.0)
    t = mot.mech.t
    paper = build_rig(L, 2 * L, [0.0, L / 2], [0.0, L / 2], noise_ug=400, quantize=False)
    wide = build_rig(L, 2 * L, [0.0, L], [0.0, L], noise_ug=400, quantize=False)
    sim = simulate_errors(paper, mot, ["analytical", "array-ekf"], range(3))
    crb0 = np.degrees(steady_rms(crb0_theta(paper, mot), t))
    pcrb = np.degrees(steady_rms(pcrb_theta(paper, mot), t))
    # The memoryless estimate sits on the per-sample bound; the filter near the PCRB.
    assert float(np.mean(sim["analytical"])) == pytest.approx(crb0, rel=0.1)
    # (The PCRB bounds the MSE averaged over the motion prior, not along one trajectory, so a
    # run may land a little below it.)
    assert pcrb * 0.7 < float(np.mean(sim["array-ekf"])) < pcrb * 1.3
    # Wider arrays do better, by bound and by simulation (the paper's Fig. 6).
    assert np.degrees(steady_rms(pcrb_theta(wide, mot), t)) < 0.8 * pcrb
    assert float(np.mean(simulate_errors(wide, mot, ["array-ekf"], range(3))["array-ekf"])) \
        < 0.8 * float(np.mean(sim["array-ekf"]))


def test_design_cli_recommends_wide_placement(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    rig_out = tmp_path / "rig.toml"
    assert main(["design", "--la", "0.3", "--lb", "0.3", "--seeds", "1", "--filters", "ekf",
                 "--motion", "gravity-impulse", "--json", "--rig-out", str(rig_out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    rec, paper = doc["recommended"], doc["paper_placement"]
    assert rec["pcrb_deg"] < paper["pcrb_deg"]
    pa = rec["positions_a_m"]
    assert max(pa) - min(pa) > 0.2  # spread along the link
    assert rig_out.exists()
    assert main(["design", "--n", "1"]) == 2
    assert main(["design", "--motion", "paper-table2-L30", "--la", "0.3", "--lb", "0.2"]) == 2
