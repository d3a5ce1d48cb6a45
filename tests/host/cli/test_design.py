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
    ends,
    kappa,
    kappa_ends,
    kappa_span,
    pcrb_theta,
    reference_motion,
    simulate_errors,
    spread,
    steady_rms,
)
from jointangle.design_figures import count_summary, fig5, fig6, fig7, floors


@pytest.mark.parametrize(("l_", "d_"), [(0.1, 0.1), (0.2, 0.05), (0.05, 0.1)])
def test_kappa_closed_form_for_two_sensors(l_: float, d_: float) -> None:
    """κ = 1/2 + (l/d)²/2 for two sensors with mean l/2 from the joint, d apart."""
    rig = build_rig(0.3, 0.6, spread(l_, d_, 2), spread(l_, d_, 2), noise_ug=400,
                    quantize=False)
    for link in ("a", "b"):
        assert kappa(rig, link) == pytest.approx(0.5 + 0.5 * (l_ / d_) ** 2, rel=1e-12)


@pytest.mark.parametrize(("l_", "d_"), [(0.1, 0.1), (0.2, 0.05)])
def test_kappa_closed_forms_for_n_sensors(l_: float, d_: float) -> None:
    """κ_span (N evenly over the span) and κ_ends (half at each end) against the matrices."""
    for n in range(2, 11):
        rig = build_rig(0.3, 0.6, spread(l_, d_, n), ends(l_, d_, n), noise_ug=400,
                        quantize=False)
        assert kappa(rig, "a") == pytest.approx(kappa_span(n, l_, d_), rel=1e-12)
        if n % 2 == 0:
            assert kappa(rig, "b") == pytest.approx(kappa_ends(n, l_, d_), rel=1e-12)
    # At fixed span each added sensor is worth less: N κ_span(N) grows towards 1 + 3 (l/d)².
    nk = [n * kappa_span(n, l_, d_) for n in range(2, 11)]
    assert np.all(np.diff(nk) > 0) and nk[-1] < 1 + 3 * (l_ / d_) ** 2


def test_sensor_count_sweep_findings() -> None:
    """The Fig. 5 sweep, small: steady error falls with N as √κ for filter and analytical
    alike; stacking the sensors at the span's ends does better (√N); and under the paper's
    whole-run score from x₀ = 0 the filter's N-effect is below its seed scatter while the
    analytical's is far above it, and one-draw curves of the filter rise where the
    analytical's never do."""
    f5 = fig5(range(12), ns=(2, 4, 10), seconds=15.0, filters=("analytical", "ekf"),
              grid_ns=(2, 4, 10), grid_filters=("analytical", "ekf"))
    sm = count_summary(f5)
    assert sm["theory_span"] == pytest.approx(sm["theory_span_closed"], rel=1e-9)
    assert sm["theory_span"] == pytest.approx(0.588, abs=0.001)  # √(κ10/κ2), l = d
    assert sm["theory_ends"] == pytest.approx(np.sqrt(2 / 10), rel=1e-9)
    an, ekf = sm["analytical"], sm["ekf"]
    for f in (an, ekf):
        assert f["monotone_span"]
        assert f["ratio_span"] == pytest.approx(sm["theory_span"], rel=0.1)
        assert f["ratio_ends"] == pytest.approx(sm["theory_ends"], rel=0.1)
        assert f["ends_hi"] < 0.85 * f["steady_hi"]  # the lever, not N alone
        assert f["fit_lo"] > 0.85 and f["fit_hi"] < 1.15
    # Whole-run score (the paper's): the start-up swamps the filter's gain.
    assert ekf["full_lo"] - ekf["full_hi"] < ekf["full_sd_lo"]
    assert ekf["start_hi"] > 3 * ekf["steady_hi"]
    assert an["full_lo"] - an["full_hi"] > 10 * an["full_sd_lo"]
    assert an["grid_rises"] == 0 and ekf["grid_rises"] >= 1


def test_placement_sweep_findings() -> None:
    """Figs. 6–7, small: error falls as d_b grows, rises with l_b, and the l_a/d_a ratio of
    link a sets the floor however link b is placed."""
    rows = fig6(range(3), l_bs=(0.2, 0.6, 1.0), d_bs=(0.05, 0.1, 0.4), seconds=15.0)["rows"]
    err = {(r["l_b"], r["d_b"]): r["ekf"] for r in rows}
    for l_b in (0.2, 0.6, 1.0):
        assert err[l_b, 0.05] > err[l_b, 0.1] > err[l_b, 0.4]
    for d_b in (0.05, 0.1):
        assert err[0.2, d_b] < err[0.6, d_b] < err[1.0, d_b]
    fl = floors(fig7(range(3), ratios=(0.5, 2.0, 5.0), l_bs=(0.2, 1.0), d_bs=(0.1, 0.4),
                     seconds=15.0))
    best = [fl[r]["ekf"] for r in (0.5, 2.0, 5.0)]
    assert best[0] < 0.8 * best[1] and best[1] < 0.8 * best[2]


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
    # More sensors on the same spans: stacked at the ends is plain √N averaging, exactly;
    # spread evenly it is worth less (interior sensors add little lever) but still helps.
    for g in doc["more_sensors"]["error_factor_vs_two"]:
        assert g["ends"] == pytest.approx(np.sqrt(2 / g["n"]), rel=1e-9)
        assert g["ends"] < g["even"] < 1.0
    assert main(["design", "--n", "1"]) == 2
    for rate in ("5", "100000"):  # outside the board's 10-1000 Hz (1 Hz used to crash)
        assert main(["design", "--rate", rate]) == 2
    assert main(["design", "--n", "9", "--rig-out", str(tmp_path / "big.toml")]) == 2
    assert main(["design", "--motion", "paper-table2-L30", "--la", "0.3", "--lb", "0.2"]) == 2
