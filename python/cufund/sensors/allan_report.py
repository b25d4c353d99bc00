"""`cufund allan`: simulate a static IMU, write its raw record, an Allan-deviation plot and the fitted
noise parameters next to the configured ones — the check every IMU user runs on real hardware."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .allan import allan_deviation, fit_allan
from .imu import IMU_PRESETS, ImuModel, imu_preset

__all__ = ["add_arguments", "allan_report", "run"]


def allan_report(imu: str, duration_s: float, out: str | Path, seed: int = 0) -> dict:
    """Writes ``imu.npz``, ``allan.png`` and ``allan.json`` into ``out``; returns the JSON content."""
    if not (np.isfinite(duration_s) and duration_s >= 100.0):
        raise ValueError(f"duration must be at least 100 s to resolve the random walk, got {duration_s!r}")
    params = imu_preset(imu)
    model = ImuModel(params, seed=seed)
    dt = 1.0 / params.rate_hz
    k = int(round(duration_s / dt))
    acc, gyr = model.measure_static(k)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "imu.npz", t=np.arange(k) * dt, accel=acc, gyro=gyr, rate_hz=params.rate_hz)

    tau, adev_a = allan_deviation(acc, dt)
    _, adev_g = allan_deviation(gyr, dt)
    i1 = int(np.argmin(np.abs(np.log(tau))))  # tau closest to 1 s
    report: dict = {
        "imu": imu,
        "rate_hz": params.rate_hz,
        "duration_s": k * dt,
        "seed": seed,
        "units": {
            "accel_noise_density": "m/s^2/sqrt(Hz)",
            "accel_random_walk": "m/s^3/sqrt(Hz)",
            "gyro_noise_density": "rad/s/sqrt(Hz)",
            "gyro_random_walk": "rad/s^2/sqrt(Hz)",
        },
        "axes": {},
    }
    for sensor, adev, spec in (("accel", adev_a, params.accel), ("gyro", adev_g, params.gyro)):
        nd, rw, _ = spec.per_axis(3)
        for axis, name in enumerate("xyz"):
            fit = fit_allan(tau, adev[:, axis], record_s=k * dt)
            report["axes"][f"{sensor}_{name}"] = {
                "noise_density": {
                    "configured": nd[axis],
                    "fitted": fit.white_noise_density,
                    "adev_at_1s": float(adev[i1, axis]),
                    "relative_error": _rel(fit.white_noise_density, nd[axis]),
                },
                "random_walk": {
                    "configured": rw[axis],
                    "fitted": fit.bias_random_walk,
                    "relative_error": _rel(fit.bias_random_walk, rw[axis]),
                },
            }
    (out / "allan.json").write_text(json.dumps(report, indent=2))
    _plot(out / "allan.png", tau, adev_a, adev_g, params, imu)
    return report


def _rel(fitted: float, configured: float) -> float | None:
    return None if configured == 0 else (fitted - configured) / configured


def _plot(path: Path, tau, adev_a, adev_g, params, imu: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, adev, spec, label, unit in (
        (axes[0], adev_a, params.accel, "accelerometer", "m/s$^2$"),
        (axes[1], adev_g, params.gyro, "gyroscope", "rad/s"),
    ):
        nd, rw, _ = spec.per_axis(3)
        for axis, name in enumerate("xyz"):
            ax.loglog(tau, adev[:, axis], label=f"{name}")
        ax.loglog(tau, nd[0] / np.sqrt(tau), "k--", lw=0.8, label="configured N/sqrt(tau)")
        if rw[0] > 0:
            ax.loglog(tau, rw[0] * np.sqrt(tau / 3), "k:", lw=0.8, label="configured K sqrt(tau/3)")
        ax.set_xlabel("tau [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(f"{imu} {label}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--imu", default="icm42688p", choices=sorted(IMU_PRESETS), help="IMU preset")
    parser.add_argument("--duration", type=float, default=3600.0, help="record length [s] (default 3600)")
    parser.add_argument("--out", default="runs/allan", help="output folder")
    parser.add_argument("--seed", type=int, default=0)


def run(args: argparse.Namespace) -> int:
    report = allan_report(args.imu, args.duration, args.out, args.seed)
    for axis, r in report["axes"].items():
        nd, rw = r["noise_density"], r["random_walk"]
        rw_err = "n/a" if rw["relative_error"] is None else f"{100 * rw['relative_error']:+.1f}%"
        print(
            f"{axis:8s} noise density {nd['fitted']:.3e} (configured {nd['configured']:.3e}, "
            f"{100 * nd['relative_error']:+.1f}%)  random walk {rw['fitted']:.3e} (configured "
            f"{rw['configured']:.3e}, {rw_err})"
        )
    print(f"wrote {Path(args.out) / 'allan.json'}, allan.png, imu.npz")
    return 0
