"""Figures in the spirit of the paper's Figs. 3–4: estimates against truth, and the error."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, wrap
from jointangle.io.atomic import atomic_path
from jointangle.io.csv_formats import Truth


def image_formats() -> dict[str, str]:
    """The image formats matplotlib writes: file extension (no dot) -> description."""
    from matplotlib.figure import Figure  # deferred: matplotlib loads only for an image output

    formats: dict[str, str] = Figure().canvas.get_supported_filetypes()
    return formats


def image_format(path: str | Path, option: str | None = None) -> str:
    """The format of an image output, from its extension; an extension matplotlib cannot
    write (or none: matplotlib would add .png to the name) is an InputError naming `option`."""
    ext = Path(path).suffix.lstrip(".").lower()
    formats = image_formats()
    if ext in formats:
        return ext
    known = ", ".join(f".{e}" for e in sorted(formats))
    what = f"unknown image format .{ext}" if ext else "no file extension to give the format"
    raise InputError(f"{what}: name the image with one of {known}", path=path, field=option)


def plot_estimates(path: str | Path, t: np.ndarray, estimates: Mapping[str, Estimates],
                   truth: Truth | None, title: str) -> None:
    """θ, ω_a, ω_b of each estimator over time (truth in black), and the θ error if truth
    is known. Writes the image to `path` (format from its extension: `image_format`), whole
    or not at all. NaN (an estimator's rates where it has none) leaves a gap."""
    fmt = image_format(path)
    # Deferred: matplotlib (with pyplot ~0.3 s) loads only when a figure is drawn, and takes its
    # backend before pyplot is imported.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # One colour per estimator across every panel.
    colours = {name: f"C{i}" for i, name in enumerate(estimates)}
    rows = 4 if truth is not None else 3
    fig, axes = plt.subplots(rows, 1, figsize=(11, 2.3 * rows + 0.6), sharex=True,
                             constrained_layout=True)
    series = (("θ_ab (°)", "theta"), ("ω_a (°/s)", "omega_a"), ("ω_b (°/s)", "omega_b"))
    for ax, (label, attr) in zip(axes, series, strict=False):
        if truth is not None:
            ax.plot(t, np.degrees(getattr(truth, attr)), color="black", lw=2.2, label="truth")
        for name, est in estimates.items():
            values = np.degrees(getattr(est, attr)[0])
            if attr == "theta" and truth is not None:
                # Draw on the truth's branch so a wrap at ±180° does not jump across the plot.
                values = np.degrees(truth.theta + wrap(est.theta[0] - truth.theta))
            if np.isfinite(values).any():
                ax.plot(t, values, lw=1.0, label=name, color=colours[name])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", ncols=min(5, len(estimates) + 1), fontsize=8)
    if truth is not None:
        ax = axes[3]
        for name, est in estimates.items():
            err = np.degrees(wrap(est.theta[0] - truth.theta))
            # Samples whose truth is NaN (unknown) are not scored.
            scored = np.isfinite(err) & ((t >= 5.0) if (t >= 5.0).any() else True)
            rms = f"steady RMS {np.sqrt(np.mean(err[scored] ** 2)):.2f}°" if scored.any() \
                else "no truth to score"
            ax.plot(t, err, lw=0.9, label=f"{name} ({rms})", color=colours[name])
        ax.axvline(5.0, color="grey", ls=":", lw=1)
        ax.set_ylabel("θ error (°)")
        ax.legend(loc="upper right", ncols=2, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format=fmt)
    except RuntimeError as exc:  # a format needing a missing tool (.pgf: LaTeX)
        first_line = str(exc).partition("\n")[0]
        raise InputError(f"cannot write .{fmt}: {first_line}", path=path) from None
    finally:
        plt.close(fig)
