"""Filter consistency over a Monte Carlo set: NEES and NIS inside their 95 % chi-square bounds.

With M runs, M times the run-averaged NEES of a d-dimensional error is chi-square with M*d degrees of
freedom when the filter is consistent (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to
Tracking and Navigation", ch. 5.4); likewise NIS. The filter is configured with the simulator's true
noise levels, and the truth's speed and yaw rate are random walks of the intensities the filter assumes:
consistency is about the filter's arithmetic and linearisation, not about tuning margins.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable

import numpy as np
import pytest
from scipy.stats import chi2

from estimator.config import EstimatorConfig
from logs.topics import ESTIMATOR_INNOVATIONS
from tests.estimator import rover_sim
from tests.estimator.sim_run import SIM_DATUM, Run

RUNS = 12
SECONDS = 60.0
SETTLED_S = 20.0  # after the initial transient (first fixes, heading prior, scale and bias learnt)
SHARE_INSIDE = 0.90
SPEED_WALK = 0.05  # m/s^2 per sqrt(Hz): std of the white acceleration driving the speed
YAW_RATE_WALK = 0.05  # rad/s^2 per sqrt(Hz)

MATCHED = EstimatorConfig(
    gps_noise_m=rover_sim.GPS_STD_M,
    gyro_noise_rps=rover_sim.GYRO_STD_RPS,
    # Mean of two wheels; yaw rate = difference / (track * skid factor): 0.55 m * 1.6.
    odom_speed_noise_mps=rover_sim.WHEEL_STD_MPS / math.sqrt(2.0),
    odom_yaw_rate_noise_rps=rover_sim.WHEEL_STD_MPS * math.sqrt(2.0) / (0.55 * 1.6),
    accel_process_noise=SPEED_WALK,
    yaw_accel_process_noise=YAW_RATE_WALK,
    # The simulated wheels obey the skid-steer kinematics exactly.
    odom_yaw_rate_relative_noise=0.0,
    # The simulated gyro bias and odometry scale are constants: (almost) no random walk on them either.
    gyro_bias_walk=1e-6,
    odom_scale_walk=1e-5,
    datum_lat_deg=SIM_DATUM.lat_deg,
    datum_lon_deg=SIM_DATUM.lon_deg,
    datum_alt_m=SIM_DATUM.alt_m,
)


def random_walk_profile(rng: np.random.Generator) -> Callable[[float], tuple[float, float]]:
    """Speed and yaw rate as the filter models them: random walks, from a gentle forward arc."""
    steps = round(SECONDS * 1e9 / rover_sim.STEP_NS) + 1
    dt = rover_sim.STEP_NS * 1e-9
    speed = 0.8 + np.cumsum(rng.normal(0.0, SPEED_WALK * math.sqrt(dt), steps))
    yaw_rate = 0.1 + np.cumsum(rng.normal(0.0, YAW_RATE_WALK * math.sqrt(dt), steps))
    return lambda t_s: (float(speed[round(t_s / dt)]), float(yaw_rate[round(t_s / dt)]))


def _bounds(dof: int) -> tuple[float, float]:
    """95 % two-sided bounds of a run-averaged chi-square statistic with ``dof`` per run."""
    return float(chi2.ppf(0.025, RUNS * dof) / RUNS), float(chi2.ppf(0.975, RUNS * dof) / RUNS)


def _share_inside(averages: np.ndarray, dof: int) -> float:
    low, high = _bounds(dof)
    return float(np.mean((averages >= low) & (averages <= high)))


@pytest.fixture(scope="module")
def monte_carlo() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """NEES per (run, step) of (x, y, yaw), and NIS per (run, update) of each sensor."""
    nees_runs = []
    nis_runs: dict[str, list[list[float]]] = defaultdict(list)
    for seed in range(RUNS):
        rng = np.random.default_rng(1000 + seed)
        run = Run(MATCHED)
        # The heading prior is as uncertain as it claims: truth drawn around it with its std.
        run.estimator.set_initial_heading(2.0, 0.05)
        start_yaw = 2.0 + float(rng.normal(0.0, 0.05))
        run.drive(seed, SECONDS, start_yaw=start_yaw, profile=random_walk_profile(rng))
        nees = []
        for step in run.steps:
            if step.t_s < SETTLED_S:
                continue
            error = np.array([step.pose.x - step.true_x, step.pose.y - step.true_y, step.yaw_error_rad])
            p = step.pose.covariance[:3, :3]
            nees.append(float(error @ np.linalg.solve(p, error)))
        nees_runs.append(nees)
        per_sensor: dict[str, list[float]] = defaultdict(list)
        for topic, log_time, message in run.sink.records:
            if topic == ESTIMATOR_INNOVATIONS and log_time >= SETTLED_S * 1e9:
                per_sensor[message["sensor"]].append(message["nis"])
        for sensor, values in per_sensor.items():
            nis_runs[sensor].append(values)
    return np.array(nees_runs), {k: np.array(v) for k, v in nis_runs.items()}


def test_nees_inside_its_95_percent_bounds(monte_carlo):
    nees, _ = monte_carlo
    share = _share_inside(nees.mean(axis=0), dof=3)
    assert share >= SHARE_INSIDE, f"only {share:.1%} of steps inside the NEES bounds {_bounds(3)}"


@pytest.mark.parametrize(("sensor", "dof"), [("gps", 2), ("gyro", 1), ("odometry", 2)])
def test_nis_inside_its_95_percent_bounds(monte_carlo, sensor, dof):
    _, nis = monte_carlo
    share = _share_inside(nis[sensor].mean(axis=0), dof=dof)
    assert share >= SHARE_INSIDE, f"only {share:.1%} of {sensor} updates inside the NIS bounds {_bounds(dof)}"
