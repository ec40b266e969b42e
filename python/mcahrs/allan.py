"""``mcahrs allan FILE``: IMU noise parameters from the Allan deviation of a static recording.

The Gauss-Markov and white-noise parameters of the INS (docs/ALGORITHMS.md 10) and of the
attitude filter (section 7) come from here (DESIGN.md 6). Per axis of the gyro and of the
accelerometer:

1. the overlapping Allan deviation ``sigma(tau)`` of the rate samples (``allantools.oadev``,
   ``data_type="freq"``) on octave-spaced ``tau`` from one sample to a tenth of the record;
2. the IEEE read-off of the bias instability: ``B = min sigma / 0.664`` at ``tau_B``;
3. a weighted non-negative least-squares fit of the Allan variance with the standard terms, each
   a straight line of known slope on the log-log plot, plus a first-order Gauss-Markov bias::

       sigma^2(tau) = 3 Q^2 / tau^2      quantization               (slope -1)
                    + N^2 / tau          angle/velocity random walk (slope -1/2)
                    + GM(tau; q, T_c)    Gauss-Markov bias: q^2 tau / 3 below T_c, a hump,
                                         (q T_c)^2 / tau above it
                    + K^2 tau / 3        rate random walk           (slope +1/2)

   ``GM = (q T_c)^2 / tau [1 - T_c/(2 tau) (3 - 4 e^(-tau/T_c) + e^(-2 tau/T_c))]``. ``T_c`` runs
   over a log grid from 5 tau_min to tau_max / 4 (where its hump is inside the measured range),
   the other coefficients come from NNLS for each, and the best weighted residual is kept. The
   Gauss-Markov term stays only when it cuts the residual of the fit without it to 35 % (spurious
   ones, fitted to the scatter of white noise and random walk, cut it by half at most). Weights:
   ``1 / sigma^2(tau)`` (relative error, as a fit on the log plot) times the square root of the
   number of clusters at each ``tau`` (the long-tau points are the noisy ones).

Parameters in the form the filters take (``--out`` JSON), the largest of the three axes:

* INS (``mca_ins_config_t``): ``gyro_noise_rps``, ``accel_noise_mps2`` = N; the bias is one
  first-order Gauss-Markov process: ``*_bias_tau_s`` = the fitted ``T_c`` (median of the axes,
  when at least two axes resolve one; else 0, a random walk) and driving density
  ``*_bias_rw_* = sqrt(q^2 + K^2)`` (steady-state std ``q sqrt(T_c / 2)``);
* attitude (``mca_att_config_t``): ``gyro_noise_rps = N_g``, ``gyro_bias_rw_rps2 = sqrt(q^2 + K^2)``
  (below ``T_c`` a Gauss-Markov bias is a random walk of density ``q``).

A term the record is too short to resolve (rate random walk needs ``tau`` well beyond where it
meets the white noise) is fitted as 0 and reported as such, with the upper bound the longest
``tau`` allows. Recordings are read with :func:`mcahrs.io.loaders.load`, or from an ``.npz``
holding ``t_us``, ``gyro_rps`` (n x 3), ``accel_mps2`` (n x 3).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["AxisNoise", "allan_deviation", "analyse", "fit_noise", "main_allan", "to_configs"]

_BI = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664: Allan deviation of bias instability B
_GM_PEAK = 1.89  # a Gauss-Markov Allan deviation peaks at tau = 1.89 tau_c


@dataclass
class AxisNoise:
    """Fitted noise terms of one axis (rate units: rad/s or m/s^2)."""

    n: float  # white noise density (ARW / VRW), unit/sqrt(Hz)
    b: float  # bias instability read off the curve, min sigma / 0.664, unit
    tau_b_s: float  # where the measured deviation is minimal
    gm_q: float  # Gauss-Markov driving density, unit/sqrt(s) (0: none resolved)
    gm_tau_s: float  # its correlation time T_c (0: none)
    k: float  # rate random walk, unit/sqrt(s)
    q: float  # quantization, unit*s
    k_upper: float  # K, or when K is not resolved the largest K the longest tau allows

    @property
    def gm_sigma(self) -> float:
        """Steady-state standard deviation of the Gauss-Markov bias."""
        return self.gm_q * math.sqrt(self.gm_tau_s / 2.0)

    def model(self, tau: np.ndarray) -> np.ndarray:
        """The fitted Allan deviation at ``tau``."""
        return np.sqrt(
            3 * self.q**2 / tau**2
            + self.n**2 / tau
            + gm_avar(tau, self.gm_q, self.gm_tau_s)
            + self.k**2 * tau / 3
        )


def gm_avar(tau: np.ndarray, q: float, tc: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov rate with driving density q and time tc."""
    if q <= 0.0 or tc <= 0.0:
        return np.zeros_like(tau)
    a = tau / tc
    return (q * tc) ** 2 / tau * (1.0 - (3.0 - 4.0 * np.exp(-a) + np.exp(-2.0 * a)) / (2.0 * a))


def allan_deviation(x: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples ``x`` at ``fs_hz``: (tau, adev, clusters)."""
    import allantools

    n = len(x)
    m = np.unique(np.round(np.logspace(0, math.log10(max(n // 10, 2)), 60)).astype(int))
    taus = m / fs_hz
    tau, adev, _, _ = allantools.oadev(np.asarray(x, float), rate=fs_hz, data_type="freq", taus=taus)
    clusters = n / (tau * fs_hz)
    return np.asarray(tau), np.asarray(adev), clusters


def fit_noise(tau: np.ndarray, adev: np.ndarray, clusters: np.ndarray) -> AxisNoise:
    """The read-off of B and the weighted NNLS fit with a T_c grid (module docstring)."""
    from scipy.optimize import nnls

    ok = np.isfinite(adev) & (adev > 0)
    tau, var, cl = tau[ok], adev[ok] ** 2, clusters[ok]
    kmin = int(np.argmin(var))
    w = np.sqrt(np.maximum(cl - 1.0, 1.0)) / var
    fixed = np.stack([3.0 / tau**2, 1.0 / tau, tau / 3.0], axis=1)
    coef0, r0 = nnls(fixed * w[:, None], var * w)
    best = (r0, np.append(coef0, 0.0), 0.0)
    # A Gauss-Markov time is identifiable only when its hump (at 1.89 T_c) lies inside the measured
    # range: much shorter it is white noise, much longer a rate random walk.
    lo, hi = 5.0 * tau[0], tau[-1] / 4.0
    for tc in np.logspace(math.log10(lo), math.log10(hi), 40) if hi > lo else []:
        coef, rnorm = nnls(np.column_stack([fixed, gm_avar(tau, 1.0, tc)]) * w[:, None], var * w)
        if rnorm < best[0]:
            best = (rnorm, coef, float(tc))
    # Parsimony: on simulated white + random-walk records a spurious Gauss-Markov term cuts the
    # weighted residual by up to half; a real one (sigma 2e-4 rad/s, 100 s, 2 h) to 0.1-0.2.
    if best[0] > 0.35 * r0:
        best = (r0, np.append(coef0, 0.0), 0.0)
    _, coef, tc = best
    q2, n2, k2 = coef[:3]
    gm_q = math.sqrt(coef[3]) if tc > 0.0 and coef[3] > 0.0 else 0.0
    k_upper = math.sqrt(k2) if k2 > 0 else float(np.sqrt(3.0 * var[-1] / tau[-1]))
    return AxisNoise(
        n=math.sqrt(n2),
        b=math.sqrt(var[kmin]) / _BI,
        tau_b_s=float(tau[kmin]),
        gm_q=gm_q,
        gm_tau_s=tc if gm_q > 0.0 else 0.0,
        k=math.sqrt(k2),
        q=math.sqrt(q2),
        k_upper=k_upper,
    )


def analyse(t_us: np.ndarray, gyro: np.ndarray, accel: np.ndarray) -> dict[str, Any]:
    """Allan deviation and fitted noise of every axis; ``fs`` from the median sample interval."""
    t_us = np.asarray(t_us, np.int64)
    if len(t_us) < 100:
        raise ValueError(f"need at least 100 samples for an Allan analysis, got {len(t_us)}")
    fs = 1e6 / float(np.median(np.diff(t_us)))
    out: dict[str, Any] = {"fs_hz": fs, "duration_s": (t_us[-1] - t_us[0]) * 1e-6, "n_samples": len(t_us)}
    for name, data in (("gyro", np.asarray(gyro, float)), ("accel", np.asarray(accel, float))):
        axes = {}
        for i, ax in enumerate("xyz"):
            x = data[:, i] - np.mean(data[:, i])
            tau, adev, cl = allan_deviation(x, fs)
            axes[ax] = {"tau_s": tau, "adev": adev, "fit": fit_noise(tau, adev, cl)}
        out[name] = axes
    return out


def to_configs(res: dict[str, Any]) -> dict[str, Any]:
    """The noise parameters as ``mca_ins_config_t`` / ``mca_att_config_t`` fields (module docstring)."""
    cfg: dict[str, Any] = {"ins": {}, "att": {}}
    for sensor, n_name, rw_name, tau_name in (
        ("gyro", "gyro_noise_rps", "gyro_bias_rw_rps2", "gyro_bias_tau_s"),
        ("accel", "accel_noise_mps2", "accel_bias_rw_mps3", "accel_bias_tau_s"),
    ):
        fits = [res[sensor][ax]["fit"] for ax in "xyz"]
        cfg["ins"][n_name] = max(f.n for f in fits)
        cfg["ins"][rw_name] = max(math.hypot(f.gm_q, f.k) for f in fits)
        taus = [f.gm_tau_s for f in fits if f.gm_tau_s > 0.0]
        cfg["ins"][tau_name] = max(1.0, float(np.median(taus))) if len(taus) >= 2 else 0.0
        if sensor == "gyro":
            cfg["att"]["gyro_noise_rps"] = cfg["ins"][n_name]
            cfg["att"]["gyro_bias_rw_rps2"] = cfg["ins"][rw_name]
    return cfg


def _summary(res: dict[str, Any]) -> dict[str, Any]:
    per_axis = {}
    for sensor in ("gyro", "accel"):
        per_axis[sensor] = {
            ax: {**asdict(res[sensor][ax]["fit"]), "gm_sigma": res[sensor][ax]["fit"].gm_sigma}
            for ax in "xyz"
        }
    return per_axis


def plot(res: dict[str, Any], path: Path, title: str) -> None:
    """Log-log Allan deviation per axis with the fitted terms as lines of slope -1, -1/2, 0, +1/2."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(13, 5))
    for axp, sensor, unit in ((axs[0], "gyro", "rad/s"), (axs[1], "accel", "m/s^2")):
        for (ax, d), color in zip(res[sensor].items(), ("C0", "C1", "C2"), strict=True):
            tau, adev, f = d["tau_s"], d["adev"], d["fit"]
            axp.loglog(tau, adev, "o", ms=3, color=color, label=f"{ax}")
            axp.loglog(
                tau,
                f.model(tau),
                "-",
                color=color,
                lw=1.2,
                label=f"{ax} fit: N={f.n:.2e}, K={f.k:.2e}, GM q={f.gm_q:.1e} Tc={f.gm_tau_s:.0f}s",
            )
            for coef, expo, style in ((f.n, -0.5, "--"), (f.k / math.sqrt(3), 0.5, "-.")):
                if coef > 0:
                    axp.loglog(tau, coef * tau**expo, style, color=color, lw=0.8, alpha=0.7)
            axp.loglog([f.tau_b_s], [_BI * f.b], "s", color=color, mfc="none", ms=8)
        axp.set_xlabel("tau [s]")
        axp.set_ylabel(f"Allan deviation [{unit}]")
        axp.set_title(f"{sensor}: slopes -1/2 (N, dashed), +1/2 (K, dash-dot), B read-off (square)")
        axp.grid(True, which="both", alpha=0.3)
        axp.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _load(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    if path.suffix == ".npz":
        d = np.load(path)
        return d["t_us"], d["gyro_rps"], d["accel_mps2"], path.name
    from mcahrs.io.loaders import load

    rec = load(path)
    return rec.imu["t_us"], rec.imu["gyro_rps"], rec.imu["accel_mps2"], rec.name


def main_allan(argv: list[str] | None = None) -> int:
    """CLI: ``mcahrs allan FILE [--start S] [--duration S] [--out JSON] [--plot PNG]``. Returns 0, or
    2 on a usage or input error (message on stderr)."""
    ap = argparse.ArgumentParser(prog="mcahrs allan", description=__doc__.splitlines()[0])
    ap.add_argument("file", type=Path, help="recording (.ulg, comma2k19 folder, car csv/tag/pos, or .npz)")
    ap.add_argument(
        "--start", type=float, default=0.0, help="start of the static segment, s from the first sample"
    )
    ap.add_argument(
        "--duration", type=float, default=None, help="length of the static segment, s (default: all)"
    )
    ap.add_argument("--out", type=Path, default=None, help="write the noise parameters as JSON here")
    ap.add_argument("--plot", type=Path, default=None, help="write the log-log plot (PNG) here")
    a = ap.parse_args(argv)
    try:
        t_us, gyro, accel, name = _load(a.file)
        t_rel = (np.asarray(t_us, np.int64) - int(t_us[0])) * 1e-6
        sel = t_rel >= a.start
        if a.duration is not None:
            sel &= t_rel < a.start + a.duration
        res = analyse(np.asarray(t_us)[sel], np.asarray(gyro)[sel], np.asarray(accel)[sel])
    except (OSError, ValueError, KeyError) as exc:
        print(f"mcahrs allan: {a.file}: {exc}", file=sys.stderr)
        return 2
    cfg = to_configs(res)
    doc = {
        "source": str(a.file),
        "recording": name,
        "segment_s": [a.start, a.start + res["duration_s"]],
        "fs_hz": res["fs_hz"],
        "n_samples": res["n_samples"],
        **cfg,
        "per_axis": _summary(res),
        "note": "static segment assumed; terms the record cannot resolve are 0 (see k_upper)",
    }
    for sensor in ("gyro", "accel"):
        for ax in "xyz":
            f = res[sensor][ax]["fit"]
            print(
                f"{sensor} {ax}: N {f.n:.3e}  B {f.b:.3e} (tau_B {f.tau_b_s:.1f} s)  GM q {f.gm_q:.2e} "
                f"T_c {f.gm_tau_s:.0f} s (sigma {f.gm_sigma:.2e})  K {f.k:.3e}"
                f"{'' if f.k > 0 else f' (unresolved, <= {f.k_upper:.1e})'}  Q {f.q:.1e}"
            )
    print("ins:", json.dumps(cfg["ins"]))
    print("att:", json.dumps(cfg["att"]))
    if a.out is not None:
        a.out.write_text(json.dumps(doc, indent=2))
    if a.plot is not None:
        plot(res, a.plot, f"{name}: {res['duration_s']:.0f} s at {res['fs_hz']:.0f} Hz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main_allan())
