"""The paper's placement studies (Woods & Vikas Figs. 5–7) redone: simulation (EKF and ours,
noise seeds) beside the PCRB and the per-sample bound, as PNGs plus a Markdown summary with the
numbers. Motion: the slider-crank, θ_a = 45° sin(2π·0.2 Hz·t), 30 s at 100 Hz, 400 µg/√Hz, no
quantisation (the paper's simulation settings)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jointangle.design import (
    build_rig,
    crb0_theta,
    pcrb_theta,
    reference_motion,
    simulate_errors,
    spread,
    steady_rms,
)

NOISE_UG = 400.0


def _point(la: float, lb: float, da: list[float], db: list[float], filters: list[str],
           seeds: range) -> dict[str, float]:
    mot = reference_motion("paper-table2-L30", la, lb)
    rig = build_rig(la, lb, da, db, noise_ug=NOISE_UG, quantize=False)
    t = mot.mech.t
    row = {f: float(np.mean(v)) for f, v in simulate_errors(rig, mot, filters, seeds).items()}
    row["pcrb"] = float(np.degrees(steady_rms(pcrb_theta(rig, mot), t)))
    row["crb0"] = float(np.degrees(steady_rms(crb0_theta(rig, mot), t)))
    return row


def fig5(seeds: range) -> dict[str, Any]:
    """Error vs number of sensors: L_a = 20, L_b = 25 cm, l = d = 10 cm on both links."""
    la, lb, l_, d_ = 0.20, 0.25, 0.10, 0.10
    filters = ["smooth", "ekf", "array-ekf"]
    both, vary_b = [], []
    for n in range(2, 11):
        both.append({"n": n, **_point(la, lb, spread(l_, d_, n), spread(l_, d_, n), filters,
                                      seeds)})
        vary_b.append({"n": n, **_point(la, lb, spread(l_, d_, 5), spread(l_, d_, n), filters,
                                        seeds)})
    return {"both": both, "na5": vary_b, "filters": filters}


def fig6(seeds: range) -> dict[str, Any]:
    """Error vs l_b and d_b: L_a = 20, L_b = 200 cm, l_a = d_a = 10 cm."""
    la, lb = 0.20, 2.0
    rows = []
    for l_b in (0.2, 0.4, 0.6, 0.8, 1.0):
        for d_b in (0.05, 0.1, 0.2, 0.4):
            rows.append({"l_b": l_b, "d_b": d_b, **_point(
                la, lb, spread(0.1, 0.1, 2), spread(l_b, d_b, 2), ["ekf"], seeds)})
    return {"rows": rows}


def fig7(seeds: range) -> dict[str, Any]:
    """Error vs d_b for l_a/d_a = 0.5, 1, 2, 5 (l_a = 10 cm) and l_b = 20…100 cm."""
    la, lb = 0.20, 2.0
    rows = []
    for ratio in (0.5, 1.0, 2.0, 5.0):
        d_a = 0.1 / ratio
        for l_b in (0.2, 0.6, 1.0):
            for d_b in (0.05, 0.1, 0.2, 0.4):
                rows.append({"ratio": ratio, "l_b": l_b, "d_b": d_b, **_point(
                    la, lb, spread(0.1, d_a, 2), spread(l_b, d_b, 2), ["ekf"], seeds)})
    return {"rows": rows}


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_fig5(data: dict[str, Any], path: Path) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, key, title in ((axes[0], "na5", "N_a = 5, N_b varied"),
                           (axes[1], "both", "N_a = N_b = N")):
        rows = data[key]
        n = [r["n"] for r in rows]
        for i, f in enumerate(data["filters"]):
            ax.plot(n, [r[f] for r in rows], "o-", color=f"C{i}", label=f"{f} (simulated)")
        ax.plot(n, [r["pcrb"] for r in rows], "k--", label="PCRB (array model)")
        ax.set_yscale("log")
        ax.set_xlabel("sensors per link" if key == "both" else "N_b")
        ax.set_ylabel("steady RMS θ error (°)")
        ax.set_title(title)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    fig.suptitle("Fig. 5 redone: error vs number of accelerometers (L_a=20, L_b=25, l=d=10 cm)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_fig6(data: dict[str, Any], path: Path) -> None:
    plt = _plt()
    rows = data["rows"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    lbs = sorted({r["l_b"] for r in rows})
    dbs = sorted({r["d_b"] for r in rows})
    for i, lb in enumerate(lbs):
        sel = [r for r in rows if r["l_b"] == lb]
        axes[0].plot([1 / r["d_b"] for r in sel], [r["ekf"] for r in sel], "o-", color=f"C{i}",
                     label=f"l_b = {lb * 100:.0f} cm")
        axes[0].plot([1 / r["d_b"] for r in sel], [r["pcrb"] for r in sel], "--",
                     color=f"C{i}", lw=0.8)
    for i, db in enumerate(dbs):
        sel = [r for r in rows if r["d_b"] == db]
        axes[1].plot([r["l_b"] * 100 for r in sel], [r["ekf"] for r in sel], "o-",
                     color=f"C{i}", label=f"d_b = {db * 100:.0f} cm")
        axes[1].plot([r["l_b"] * 100 for r in sel], [r["pcrb"] for r in sel], "--",
                     color=f"C{i}", lw=0.8)
    axes[0].set_xlabel("1 / d_b (1/m)")
    axes[1].set_xlabel("l_b (cm)")
    for ax in axes:
        ax.set_ylabel("steady RMS θ error (°), ekf (solid), PCRB (dashed)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Fig. 6 redone: L_a = 20 cm, L_b = 200 cm, l_a = d_a = 10 cm")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_fig7(data: dict[str, Any], path: Path) -> None:
    plt = _plt()
    rows = data["rows"]
    fig, ax = plt.subplots(figsize=(7.5, 4.5), constrained_layout=True)
    for i, ratio in enumerate(sorted({r["ratio"] for r in rows})):
        for lb in sorted({r["l_b"] for r in rows}):
            sel = [r for r in rows if r["ratio"] == ratio and r["l_b"] == lb]
            ax.plot([r["d_b"] * 100 for r in sel], [r["ekf"] for r in sel], "o-",
                    color=f"C{i}", label=f"l_a/d_a = {ratio:g}" if lb == 0.2 else None)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("d_b (cm)")
    ax.set_ylabel("steady RMS θ error (°), ekf")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("Fig. 7 redone: the floor is set by l_a/d_a (lines: l_b = 20, 60, 100 cm)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def findings(f5: dict[str, Any], f6: dict[str, Any], f7: dict[str, Any],
             table2: list[dict[str, float]]) -> list[str]:
    """The paper's qualitative findings, each stated with our numbers."""
    out = []
    both = f5["both"]
    n2, n10 = both[0], both[-1]
    na5 = f5["na5"]
    out.append(
        f"**More sensors: fewer help less than spreading two** (Fig. 5). Spreading N sensors "
        f"evenly over the same span d, 2 → 10 per link takes `ekf` {n2['ekf']:.2f}° → "
        f"{n10['ekf']:.2f}°, `array-ekf` {n2['array-ekf']:.2f}° → {n10['array-ekf']:.2f}° and "
        f"`smooth` {n2['smooth']:.2f}° → {n10['smooth']:.2f}° (PCRB {n2['pcrb']:.2f}° → "
        f"{n10['pcrb']:.2f}°), all following √κ (κ = 1/N + |r_O − r̄|²/Σ|r̃|²). With N_a = 5 "
        f"fixed, N_b 2 → 10 moves `ekf` only {na5[0]['ekf']:.2f}° → {na5[-1]['ekf']:.2f}°: the "
        "other link sets the floor. We do not reproduce the paper's 'minimal influence' for "
        "the filters in the symmetric case — the gain is real but is what doubling Σ|r̃|² by "
        "moving two sensors further apart also buys (Fig. 6), at a fifth of the hardware.")
    rows = f6["rows"]
    lb_mid = [r for r in rows if r["l_b"] == 0.6]
    out.append(
        "**Error falls as d grows** (Fig. 6, l_b = 60 cm): d_b = "
        + ", ".join(f"{r['d_b'] * 100:.0f} cm → {r['ekf']:.2f}°" for r in lb_mid)
        + " (`ekf`); PCRB " + ", ".join(f"{r['pcrb']:.2f}°" for r in lb_mid) + ".")
    d_mid = [r for r in rows if r["d_b"] == 0.1]
    out.append(
        "**Error rises with l** (Fig. 6, d_b = 10 cm): l_b = "
        + ", ".join(f"{r['l_b'] * 100:.0f} cm → {r['ekf']:.2f}°" for r in d_mid)
        + " (`ekf`); PCRB " + ", ".join(f"{r['pcrb']:.2f}°" for r in d_mid) + ".")
    r7 = f7["rows"]
    floors = []
    for ratio in sorted({r["ratio"] for r in r7}):
        best = min((r for r in r7 if r["ratio"] == ratio), key=lambda r: float(r["ekf"]))
        floors.append(f"l_a/d_a = {ratio:g}: best {best['ekf']:.2f}° "
                      f"(l_b = {best['l_b'] * 100:.0f}, d_b = {best['d_b'] * 100:.0f} cm)")
    out.append("**The l/d ratio of the worse link sets the floor** (Fig. 7): however well link "
               "b is placed, " + "; ".join(floors) + ".")
    t2 = table2
    out.append(
        "**Bounds vs simulation** (paper-table2 rigs). With two sensors κ = 1/2 + (l/d)²/2 per "
        "link; the memoryless `analytical` estimate sits on the per-sample bound (L30/L20/L10: "
        + "/".join(f"{r['crb0']:.2f}" for r in t2) + "° bound, "
        + "/".join(f"{r['analytical']:.2f}" for r in t2) + "° simulated) and the filters come "
        "close to the PCRB of our array model (PCRB " + "/".join(f"{r['pcrb']:.2f}" for r in t2)
        + "°, `array-ekf` " + "/".join(f"{r['array-ekf']:.2f}" for r in t2) + "°, `ekf` "
        + "/".join(f"{r['ekf']:.2f}" for r in t2) + "°).")
    return out


def write_placement_report(outdir: Path, n_seeds: int = 4) -> dict[str, Any]:
    outdir.mkdir(parents=True, exist_ok=True)
    seeds = range(n_seeds)
    f5, f6, f7 = fig5(seeds), fig6(seeds), fig7(seeds)
    table2 = [_point(L, 2 * L, [0.0, L / 2], [0.0, L / 2], ["analytical", "ekf", "array-ekf"],
                     seeds) for L in (0.3, 0.2, 0.1)]
    plot_fig5(f5, outdir / "fig5_sensor_count.png")
    plot_fig6(f6, outdir / "fig6_l_and_d.png")
    plot_fig7(f7, outdir / "fig7_ratio_floor.png")
    lines = [
        "# Sensor placement: the paper's Figs. 5–7 redone",
        "",
        f"Slider-crank, θ_a = 45° sin(2π·0.2 Hz·t), 30 s at 100 Hz, 400 µg/√Hz, no quantisation; "
        f"steady RMS θ error (t ≥ 5 s), mean over {n_seeds} noise seeds. Sensors: mean position "
        "l/2 from the joint, spanning d (two sensors at l/2 ± d/2; N evenly over d). PCRB = "
        "posterior Cramér–Rao bound of the array model (`jointangle.design`). Produced by "
        f"`jointangle design --paper-figures {outdir} --seeds {n_seeds}`.",
        "",
        *[f"- {s}" for s in findings(f5, f6, f7, table2)],
        "",
        "![Fig. 5](fig5_sensor_count.png)",
        "",
        "![Fig. 6](fig6_l_and_d.png)",
        "",
        "![Fig. 7](fig7_ratio_floor.png)",
        "",
    ]
    (outdir / "placement.md").write_text("\n".join(lines), encoding="utf-8")
    return {"fig5": f5, "fig6": f6, "fig7": f7, "table2": table2}
