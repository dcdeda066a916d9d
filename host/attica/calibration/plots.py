"""PNG figures of a calibration fit, before and after (matplotlib, ``pip install '.[eval]'``).

- magnetometer: the raw samples with the fitted ellipsoid, the corrected samples on the sphere of
  radius ``B`` (same scale, equal axes, rejected outliers in red), and the field magnitude before and
  after as histograms;
- accelerometer: the still positions before and after on the sphere of radius ``g``, and each
  position's magnitude error before and after;
- gyro: the raw rates over time with the still periods shaded and the fitted offsets.

Figures are 1600 px wide; at most ``MAX_POINTS`` samples are drawn (evenly spaced).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.calibration.inertial import AccelFit, GyroFit
from attica.calibration.magfit import MagFit

__all__ = ["MAX_POINTS", "plot_accel", "plot_gyro", "plot_mag", "pyplot"]

MAX_POINTS = 4000
WIDTH_PX = 1600
DPI = 100

F64 = NDArray[np.float64]


def pyplot() -> Any:
    """matplotlib.pyplot with the Agg backend, or RuntimeError naming the package to install."""
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("--plot needs matplotlib: pip install matplotlib (or '.[eval]')") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _thin(n: int) -> NDArray[np.int64]:
    return (
        np.unique(np.linspace(0, n - 1, min(n, MAX_POINTS)).astype(np.int64)) if n else np.zeros(0, np.int64)
    )


def _sphere(radius: float, n: int = 24) -> tuple[F64, F64, F64]:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n // 2))
    return radius * np.cos(u) * np.sin(v), radius * np.sin(u) * np.sin(v), radius * np.cos(v)


def _equal_axes(ax: Any, centre: F64, half: float, unit: str) -> None:
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_zlabel(f"z ({unit})")


def plot_mag(fit: MagFit, raw: NDArray[np.floating[Any]], path: str | Path, title: str = "") -> None:
    """Magnetometer samples before and after the fit, on the sphere; ``|m|`` histograms."""
    plt = pyplot()
    x = np.asarray(raw, np.float64)
    valid = np.isfinite(x).all(axis=1) & (np.abs(x).sum(axis=1) > 0.0)
    soft = np.array(fit.model.soft_iron)
    hard = np.array(fit.model.hard_iron)
    corrected = (x - hard) @ soft.T
    inl = fit.inlier_mask
    out = valid & ~inl
    fig = plt.figure(figsize=(WIDTH_PX / DPI, 6.5), dpi=DPI)
    fig.suptitle(
        f"{title + ': ' if title else ''}magnetometer fit, coverage {fit.coverage:.0%}, "
        f"residual rms {fit.before_rms:.2f} -> {fit.after_rms:.2f} uT"
    )
    ax1 = fig.add_subplot(1, 3, 1, projection="3d")
    ax2 = fig.add_subplot(1, 3, 2, projection="3d")
    sel_in = np.flatnonzero(inl)[_thin(int(inl.sum()))]
    sel_out = np.flatnonzero(out)[_thin(int(out.sum()))]
    # the fitted ellipsoid: the sphere of radius B mapped back, raw = S^-1 m + h
    sx, sy, sz = _sphere(fit.field)
    pts = np.stack([sx.ravel(), sy.ravel(), sz.ravel()], axis=1) @ np.linalg.inv(soft).T + hard
    ex, ey, ez = (pts[:, i].reshape(sx.shape) for i in range(3))
    ax1.plot_wireframe(ex, ey, ez, color="0.6", linewidth=0.4)
    ax1.scatter(*x[sel_in].T, s=2, c="tab:blue", label="samples")
    if sel_out.size:
        ax1.scatter(*x[sel_out].T, s=6, c="tab:red", label=f"rejected ({int(out.sum())})")
    half = 1.1 * float(np.max(np.abs(x[valid] - hard))) if valid.any() else fit.field
    _equal_axes(ax1, hard, half, "uT")
    ax1.set_title("before: raw samples and the fitted ellipsoid")
    ax1.legend(loc="upper left", fontsize=8)
    ax2.plot_wireframe(sx, sy, sz, color="0.6", linewidth=0.4)
    ax2.scatter(*corrected[sel_in].T, s=2, c="tab:green", label="corrected")
    if sel_out.size:
        ax2.scatter(*corrected[sel_out].T, s=6, c="tab:red", label="rejected")
    _equal_axes(ax2, np.zeros(3), 1.1 * fit.field, "uT")
    ax2.set_title(f"after: S (raw - h) on the sphere |m| = {fit.field:.2f} uT")
    ax2.legend(loc="upper left", fontsize=8)
    ax3 = fig.add_subplot(1, 3, 3)
    before = np.linalg.norm(x[inl], axis=1)
    after = np.linalg.norm(corrected[inl], axis=1)
    before = before * (fit.field / float(before.mean()))  # the same mean, to compare the spreads
    bins = np.linspace(min(before.min(), after.min()), max(before.max(), after.max()), 80)
    ax3.hist(before, bins=bins, alpha=0.6, label="before: |raw| (scaled to mean B)", color="tab:blue")
    ax3.hist(after, bins=bins, alpha=0.6, label="after: |S (raw - h)|", color="tab:green")
    ax3.axvline(fit.field, color="k", linewidth=0.8)
    ax3.set_xlabel("field magnitude (uT)")
    ax3.set_ylabel("samples")
    ax3.set_title("field magnitude: constant when calibrated")
    ax3.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_accel(fit: AccelFit, path: str | Path, title: str = "") -> None:
    """Accelerometer still positions before and after on the sphere of radius g; per-position errors."""
    plt = pyplot()
    pos = fit.positions
    a = np.array(fit.model.misalignment) * np.array(fit.model.sensitivity)
    after = (pos - np.array(fit.model.offset)) @ a.T
    fig = plt.figure(figsize=(WIDTH_PX / DPI, 6.5), dpi=DPI)
    fig.suptitle(
        f"{title + ': ' if title else ''}accelerometer fit, {fit.distinct} positions, "
        f"| |a| - g | rms {fit.before_rms:.3f} -> {fit.after_rms:.2g} m/s^2"
    )
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    sx, sy, sz = _sphere(fit.gravity)
    ax1.plot_wireframe(sx, sy, sz, color="0.7", linewidth=0.4)
    ax1.scatter(*pos.T, s=40, c="tab:blue", marker="o", label="before (raw)")
    ax1.scatter(*after.T, s=40, c="tab:green", marker="^", label="after")
    _equal_axes(ax1, np.zeros(3), 1.15 * fit.gravity, "m/s^2")
    ax1.set_title(f"still positions on the sphere |a| = g = {fit.gravity:.4g} m/s^2")
    ax1.legend(loc="upper left", fontsize=8)
    ax2 = fig.add_subplot(1, 2, 2)
    k = np.arange(pos.shape[0])
    ax2.bar(k - 0.2, fit.before, width=0.4, label="before", color="tab:blue")
    ax2.bar(k + 0.2, fit.after, width=0.4, label="after", color="tab:green")
    ax2.axhline(0.0, color="k", linewidth=0.8)
    ax2.set_xlabel("still period")
    ax2.set_ylabel("|a| - g (m/s^2)")
    ax2.set_title("magnitude error per still period")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_gyro(fit: GyroFit, gyr: NDArray[np.floating[Any]], path: str | Path, title: str = "") -> None:
    """Raw gyro rates over time, still periods shaded, fitted offsets as lines."""
    plt = pyplot()
    g = np.asarray(gyr, np.float64)
    t = np.arange(g.shape[0]) / fit.rest.rate
    fig, axes = plt.subplots(2, 1, figsize=(WIDTH_PX / DPI, 7.0), dpi=DPI, sharex=True)
    fig.suptitle(
        f"{title + ': ' if title else ''}gyro offset from {fit.rest.seconds:.1f} s still, "
        f"|rate| rms when still {fit.before_rms:.2g} -> {fit.after_rms:.2g} rad/s"
    )
    colours = ("tab:red", "tab:green", "tab:blue")
    for ax in axes:
        for a, b in fit.rest.segments:
            ax.axvspan(t[a], t[b - 1], color="0.9")
    for i, c in enumerate(colours):
        axes[0].plot(t, g[:, i], color=c, linewidth=0.6, label="xyz"[i])
    axes[0].set_ylabel("raw rate (rad/s)")
    axes[0].set_title("raw rates (still periods shaded)")
    axes[0].legend(loc="upper right", fontsize=8)
    mask = fit.rest.mask(g.shape[0])
    for i, c in enumerate(colours):
        axes[1].plot(t[mask], g[mask, i], ".", color=c, markersize=1)
        axes[1].axhline(fit.model.offset[i], color=c, linewidth=1.0, label=f"offset {'xyz'[i]}")
    axes[1].set_ylabel("still samples (rad/s)")
    axes[1].set_xlabel("time (s)")
    axes[1].set_title("still samples and the fitted offsets")
    axes[1].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
