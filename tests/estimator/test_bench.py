"""The benchmark compares like with like: our compiled EKF and the filterpy peer compute the same filter."""

from __future__ import annotations

import json

import numpy as np

from estimator.bench import GPS_EVERY, STEP_NS, make_inputs, run_benchmark
from estimator.config import EstimatorConfig
from estimator.ekf import RoverEkf
from estimator.filterpy_peer import FilterpyRoverEkf


def test_ours_and_the_filterpy_peer_give_the_same_estimate():
    config = EstimatorConfig()
    inputs = make_inputs(500, seed=3)
    ours = RoverEkf(config)
    ours.initialise(0.0, 0.0, 0.0, 0, 0.5, 0.1)
    peer = FilterpyRoverEkf(config, STEP_NS * 1e-9)
    peer.P = ours.covariance
    for k in range(500):
        ours.predict((k + 1) * STEP_NS)
        peer.predict()
        ours.update_gyro(float(inputs.gyro[k]))
        peer.update_gyro(float(inputs.gyro[k]))
        ours.update_odometry(float(inputs.speed[k]), float(inputs.yaw_rate[k]), 0.05, 0.05)
        peer.update_odometry(float(inputs.speed[k]), float(inputs.yaw_rate[k]), 0.05, 0.05)
        if (k + 1) % GPS_EVERY == 0:
            gx, gy = (float(v) for v in inputs.gps_xy[k])
            assert ours.update_position(gx, gy, 0.5, gated=False).accepted
            peer.update_position(gx, gy, 0.5)
    assert np.allclose(ours.x, peer.x, rtol=1e-7, atol=1e-9)
    assert np.allclose(ours.covariance, peer.P, rtol=1e-6, atol=1e-12)


def test_benchmark_figures_are_one_json_object_with_named_peers():
    figures = run_benchmark(cycles=200, seed=1, repeats=1)
    json.dumps(figures)
    assert set(figures["cycles_per_s"]) == {"ours", "ours_front_end", "filterpy"}
    assert all(rate > 0 for rate in figures["cycles_per_s"].values())
    for who in ("ours", "filterpy"):
        assert set(figures["us_per_operation"][who]) == {
            "predict",
            "update_gyro",
            "update_odometry",
            "update_gps",
        }
    assert figures["goal_met"] == (figures["cycles_per_s"]["ours"] >= figures["goal_cycles_per_s"])
