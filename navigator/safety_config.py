"""The ``[safety]`` table: every failsafe's threshold, in one frozen dataclass validated on load.

Defaults follow ArduPilot Rover's where it has an equivalent (crash check 2 s, GCS failsafe off by default,
battery low/critical with a debounce timer); docs/safety.md lists each failsafe with threshold and action.
"""

from __future__ import annotations

from dataclasses import dataclass

from logs.settings import Table, finite_float, shown
from navigator.fence_shape import Polygon, first_crossing, polygon_area

# A fence polygon needs at least a triangle.
MIN_FENCE_VERTICES = 3


# The progress check compares 2 s means at the two ends of its window: shorter ones would overlap.
MIN_PROGRESS_TIME_S = 4.0


@dataclass(frozen=True)
class SafetyConfig:
    """Failsafe thresholds (seconds, metres, volts, degrees). A timeout of 0 turns that failsafe off."""

    loop_stall_s: float = 0.2
    wheel_silent_s: float = 0.25
    can_fail_s: float = 0.1
    estimator_unhealthy_s: float = 0.5
    gps_budget_s: float = 3.0
    heartbeat_timeout_s: float = 3.0
    # Judged on the last ATTITUDE with a finite roll and pitch: past this the tip-over check would judge a
    # tilt that old. The simulated AHRS sends 10 a second (hil.autopilot_sim), so 1 s is ten missed in a
    # row; ArduPilot streams ATTITUDE in its EXTRA1 group (SRn_EXTRA1, Hz), which must be a few Hz.
    attitude_timeout_s: float = 1.0
    ground_link_timeout_s: float = 0.0  # off: a rover working alone must not stop when the GCS drops
    stuck_time_s: float = 2.0
    stuck_min_command_mps: float = 0.2
    stuck_max_speed_mps: float = 0.05
    # Pushed (commanded >= stuck_min_command_mps) for progress_time_s, the estimated position must move at
    # least progress_radius_m (means over 2 s at each end): Nav2's progress checker's defaults, 0.5 m in 10 s.
    progress_time_s: float = 10.0
    progress_radius_m: float = 0.5
    # A wheel commanded >= min_command, turning < max_speed and drawing >= min_current for longer than
    # wheel_stall_s is a stalled (seized) motor: HOLD, retried after wheel_stall_hold_s.
    wheel_stall_s: float = 1.0
    wheel_stall_min_command_mps: float = 0.1
    wheel_stall_max_speed_mps: float = 0.02
    wheel_stall_min_current_a: float = 2.0
    wheel_stall_hold_s: float = 2.0
    tip_margin_deg: float = 10.0
    tip_clear_deg: float = 3.0  # hysteresis: margin must exceed threshold + this to clear
    fence: tuple[tuple[float, float], ...] = ()  # ENU polygon; empty = no geofence
    battery_low_v: float = 21.0  # 6S at 3.5 V/cell
    battery_critical_v: float = 20.0  # 6S at 3.33 V/cell
    battery_debounce_s: float = 2.0  # voltage sags under load; only a sustained low counts
    battery_clear_v: float = 0.3  # hysteresis above a battery threshold before it clears
    battery_low_speed_scale: float = 0.5

    @classmethod
    def from_table(cls, table: Table) -> SafetyConfig:
        d = cls()

        def seconds(key: str, default: float) -> float:
            return table.number(key, default, lo=0.0, hi=3600.0)

        fence_raw = table.raw("fence", [])
        if not isinstance(fence_raw, list) or any(
            not isinstance(point, list) or len(point) != 2 or any(finite_float(v) is None for v in point)
            for point in fence_raw
        ):
            raise table.error(
                "fence", f"expected a list of [x, y] points in ENU metres, got {shown(fence_raw)}"
            )
        if fence_raw and len(fence_raw) < MIN_FENCE_VERTICES:
            raise table.error(
                "fence", f"a fence needs at least {MIN_FENCE_VERTICES} points, got {len(fence_raw)}"
            )
        fence = tuple((float(p[0]), float(p[1])) for p in fence_raw)
        _check_fence_shape(table, fence)
        config = cls(
            loop_stall_s=table.number("loop_stall_s", d.loop_stall_s, lo=0.001, hi=10.0),
            wheel_silent_s=seconds("wheel_silent_s", d.wheel_silent_s),
            can_fail_s=seconds("can_fail_s", d.can_fail_s),
            estimator_unhealthy_s=seconds("estimator_unhealthy_s", d.estimator_unhealthy_s),
            gps_budget_s=seconds("gps_budget_s", d.gps_budget_s),
            heartbeat_timeout_s=seconds("heartbeat_timeout_s", d.heartbeat_timeout_s),
            attitude_timeout_s=seconds("attitude_timeout_s", d.attitude_timeout_s),
            ground_link_timeout_s=seconds("ground_link_timeout_s", d.ground_link_timeout_s),
            stuck_time_s=seconds("stuck_time_s", d.stuck_time_s),
            stuck_min_command_mps=table.number("stuck_min_command_mps", d.stuck_min_command_mps, lo=0.0),
            stuck_max_speed_mps=table.number("stuck_max_speed_mps", d.stuck_max_speed_mps, lo=0.0),
            progress_time_s=_progress_time(table, d.progress_time_s),
            progress_radius_m=table.number("progress_radius_m", d.progress_radius_m, lo=0.0, hi=100.0),
            wheel_stall_s=seconds("wheel_stall_s", d.wheel_stall_s),
            wheel_stall_min_command_mps=table.number(
                "wheel_stall_min_command_mps", d.wheel_stall_min_command_mps, lo=0.0, hi=100.0
            ),
            wheel_stall_max_speed_mps=table.number(
                "wheel_stall_max_speed_mps", d.wheel_stall_max_speed_mps, lo=0.0, hi=100.0
            ),
            wheel_stall_min_current_a=table.number(
                "wheel_stall_min_current_a", d.wheel_stall_min_current_a, lo=0.0, hi=1000.0
            ),
            wheel_stall_hold_s=seconds("wheel_stall_hold_s", d.wheel_stall_hold_s),
            tip_margin_deg=table.number("tip_margin_deg", d.tip_margin_deg, lo=0.0, hi=90.0),
            tip_clear_deg=table.number("tip_clear_deg", d.tip_clear_deg, lo=0.0, hi=90.0),
            fence=fence,
            battery_low_v=table.number("battery_low_v", d.battery_low_v, lo=0.0, hi=1000.0),
            battery_critical_v=table.number("battery_critical_v", d.battery_critical_v, lo=0.0, hi=1000.0),
            battery_debounce_s=seconds("battery_debounce_s", d.battery_debounce_s),
            battery_clear_v=table.number("battery_clear_v", d.battery_clear_v, lo=0.0, hi=100.0),
            battery_low_speed_scale=table.number(
                "battery_low_speed_scale", d.battery_low_speed_scale, lo=0.0, hi=1.0
            ),
        )
        if config.battery_critical_v > config.battery_low_v:
            raise table.error(
                "battery_critical_v",
                f"must not exceed battery_low_v ({config.battery_low_v} V), "
                f"got {config.battery_critical_v} V",
            )
        table.finish()
        return config


def _check_fence_shape(table: Table, fence: Polygon) -> None:
    """A fence must enclose an area and be a simple polygon: the even-odd rule answers for any points,
    so points on one line (nothing inside: every goal refused, the rover always outside) or crossing
    edges (inside flipping at each crossing) would load and hold the rover where no one meant."""
    if not fence:
        return
    crossing = first_crossing(fence)
    if crossing is not None:
        i, j = crossing
        n = len(fence)
        raise table.error(
            "fence",
            f"edge {list(fence[i])} -> {list(fence[(i + 1) % n])} meets edge {list(fence[j])} -> "
            f"{list(fence[(j + 1) % n])}: list the points in order around the fence, so no edges cross",
        )
    if polygon_area(fence) <= 0.0:
        raise table.error("fence", f"the points {list(map(list, fence))} enclose no area (all on one line)")


def _progress_time(table: Table, default: float) -> float:
    """0 (off), or long enough for the check's two 2 s means not to overlap (4 s), at most an hour."""
    value = table.number("progress_time_s", default, lo=0.0, hi=3600.0)
    if 0.0 < value < MIN_PROGRESS_TIME_S:
        raise table.error(
            "progress_time_s",
            f"must be 0 (off) or at least {MIN_PROGRESS_TIME_S} s (a mean over 2 s at each end), got {value}",
        )
    return value
