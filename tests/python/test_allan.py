"""``mcahrs allan``: noise parameters recovered from simulated static recordings with known
parameters, the JSON accepted by the INS and attitude configurations, and a run on the static
segments of the real recordings when ../shared/data is present."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mcahrs import allan, core
from mcahrs.sim import scenario

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


def _analyse(**kw) -> tuple[dict, object]:
    res = scenario("static", gyro_lsb_rps=0.0, accel_lsb_mps2=0.0, **kw)
    imu = res.recording.imu
    return allan.analyse(imu["t_us"], imu["gyro_rps"], imu["accel_mps2"]), res.params


@pytest.mark.parametrize("seed", [1, 2])
def test_white_noise_and_rate_random_walk_are_recovered(seed: int) -> None:
    r, p = _analyse(seed=seed, duration_s=3600.0, imu_rate_hz=100.0)
    for sensor, n_true, k_true in (
        ("gyro", p.gyro_noise_rps_rthz, p.gyro_bias_rw_rps_rts),
        ("accel", p.accel_noise_mps2_rthz, p.accel_bias_rw_mps2_rts),
    ):
        fits = [r[sensor][ax]["fit"] for ax in "xyz"]
        print(
            sensor,
            [f"N {f.n:.3e} K {f.k:.2e} GM q {f.gm_q:.1e}" for f in fits],
            f"(true N {n_true:.3e}, K {k_true})",
        )
        for f in fits:
            # N: ~3.6e5 samples pin the white level to well under 1 %; 5 % leaves margin
            assert abs(f.n / n_true - 1.0) < 0.05
            # K: resolved only at tau of a few hundred s, where an hour holds ~10 clusters: the Allan
            # variance there is uncertain by 1/sqrt(2 * 10) ~ 25 %, the deviation by half that per
            # point; the fit over the whole tail lands within 35 %
            assert abs(f.k / k_true - 1.0) < 0.35
        # no Gauss-Markov bias in this recording: at most one axis fits a spurious one
        assert sum(f.gm_q > 0 for f in fits) <= 1
    cfg = allan.to_configs(r)
    assert cfg["ins"]["gyro_bias_tau_s"] == 0.0  # a random walk, as simulated
    assert abs(cfg["att"]["gyro_noise_rps"] / p.gyro_noise_rps_rthz - 1.0) < 0.05


@pytest.mark.parametrize("seed", [1, 2])
def test_gauss_markov_bias_is_recovered(seed: int) -> None:
    sigma, tc = 2e-4, 100.0
    r, _ = _analyse(
        seed=seed,
        duration_s=7200.0,
        imu_rate_hz=50.0,
        gyro_bias_rw_rps_rts=0.0,
        gyro_bias_gm_sigma_rps=sigma,
        gyro_bias_gm_tau_s=tc,
        gyro_noise_rps_rthz=2e-4,
    )
    fits = [r["gyro"][ax]["fit"] for ax in "xyz"]
    print([f"sigma {f.gm_sigma:.2e} T_c {f.gm_tau_s:.0f} s, B {f.b:.2e} at {f.tau_b_s:.0f} s" for f in fits])
    for f in fits:
        assert f.gm_q > 0.0
        # two hours hold 72 correlation times: the fitted std within 30 %; T_c within a factor 2.5
        # (the hump of a Gauss-Markov Allan curve is broad and T_c trades against the K term)
        assert abs(f.gm_sigma / sigma - 1.0) < 0.3
        assert tc / 2.5 < f.gm_tau_s < 2.5 * tc
    cfg = allan.to_configs(r)["ins"]
    assert tc / 2.5 < cfg["gyro_bias_tau_s"] < 2.5 * tc
    q_true = sigma * math.sqrt(2.0 / tc)
    assert abs(cfg["gyro_bias_rw_rps2"] / q_true - 1.0) < 0.35


def test_cli_writes_configs_the_filters_accept(tmp_path: Path) -> None:
    res = scenario("static", seed=3, duration_s=600.0, imu_rate_hz=200.0)  # default IMU, quantised
    imu = res.recording.imu
    npz = tmp_path / "static.npz"
    np.savez(npz, t_us=imu["t_us"], gyro_rps=imu["gyro_rps"], accel_mps2=imu["accel_mps2"])
    out, png = tmp_path / "noise.json", tmp_path / "allan.png"
    assert allan.main_allan([str(npz), "--out", str(out), "--plot", str(png), "--start", "10"]) == 0
    doc = json.loads(out.read_text())
    assert png.stat().st_size > 10_000
    assert doc["segment_s"][0] == 10.0 and abs(doc["segment_s"][1] - 600.0) < 0.1
    # the JSON is in the configurations' own field names and ranges
    core.ins_config(**doc["ins"])
    core.nav_config(att=doc["att"])
    # quantisation (1.07e-3 rad/s LSB) adds white noise: N is at least the simulated density
    assert doc["ins"]["gyro_noise_rps"] >= 0.95 * res.params.gyro_noise_rps_rthz
    assert set(doc["per_axis"]) == {"gyro", "accel"}


def test_cli_bad_input_returns_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert allan.main_allan([str(tmp_path / "missing.ulg")]) == 2
    npz = tmp_path / "short.npz"
    np.savez(npz, t_us=np.arange(10) * 1000, gyro_rps=np.zeros((10, 3)), accel_mps2=np.zeros((10, 3)))
    assert allan.main_allan([str(npz)]) == 2
    assert "at least 100 samples" in capsys.readouterr().err


@pytest.mark.parametrize(
    "rel,start,duration", [("car", 0.0, 20.0), ("ulog/log_61_2024-2-6-16-27-02.ulg", 0.0, 5.0)]
)
def test_real_static_segments(rel: str, start: float, duration: float, tmp_path: Path) -> None:
    path = DATA / rel
    if not path.exists():
        pytest.skip(f"{path} not present (../shared/data)")
    out = tmp_path / "noise.json"
    assert (
        allan.main_allan([str(path), "--start", str(start), "--duration", str(duration), "--out", str(out)])
        == 0
    )
    doc = json.loads(out.read_text())
    print(rel, json.dumps({"ins": doc["ins"], "att": doc["att"]}))
    # these segments are short (and the ULog's is not truly still: rotors run): only N is meaningful
    assert doc["ins"]["gyro_noise_rps"] > 0.0 and doc["ins"]["accel_noise_mps2"] > 0.0
