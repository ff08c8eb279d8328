"""Wheels that change speed faster than the body can: braking skids and launch spin, told by the IMU.

A skid-steer rover's motors stop its wheels in a tenth of a second; the body slides on for a few tenths
more. Launching, the wheels spin up first. Through such a transient the wheel speed is not the body's, and
fused as it is, it moves the estimate as the wheels do. (HIL, ``scenarios/carts.toml`` with scans, seed 1,
braking for a cart: the wheels read 0.09 m/s while the body still moved at 0.52 m/s, and the estimate said
0.11 m/s; with this module, 0.49 m/s.)

The IMU sees the body: its longitudinal specific force, less gravity's share along the slope
(``g sin(pitch)``, pitch from the AHRS), is the body's acceleration. Over a short window the change of the
wheel speed is compared with the body's change of speed (the acceleration integrated); when the wheels'
change is larger than ``threshold_mps`` and differs from the body's by more than that, on two odometry
samples in a row, the wheels are slipping along their travel. Until the wheel speed agrees with
the estimate again (within half the threshold: closer than it took to start), the speed is carried by the
IMU's acceleration (from the body's speed at its start: the estimate at the window's start plus the
body's change of speed since) and the wheels' speed is left
out. A slip that does not end within ``max_s`` ends there,
so the IMU's bias is never integrated for long.

Limits. A divergence slower than ``threshold_mps`` per window (0.6 m/s^2 with the defaults) is not told;
a slip told late starts from an estimate the wheels had already pulled; a slip ends with the body up to half
the threshold off the wheels, which the odometry then takes over. While a slip is on, the IMU's errors go
into the speed unchecked: a pitch that lags on a changing slope reads as acceleration (``g`` times the
pitch error), which ``max_s`` bounds. An acceleration beyond 1 g is a knock, not travel, and is left out.
"""

from __future__ import annotations

from collections import deque

# A sample of the other stream older than this is no evidence about the window: one source has gone quiet.
_FRESH_NS = 100_000_000
_END_SHARE = 0.5
# Odometry samples in a row that must look like a slip before one begins: one noisy wheel sample is not one.
_CONFIRM_SAMPLES = 2
# A body acceleration beyond 1 g is no ground vehicle's travel (friction-limited, mu <= 1): a bump or a knock
# on the IMU, left out.
STANDARD_GRAVITY_MPS2 = 9.80665
MAX_BODY_ACCEL_MPS2 = STANDARD_GRAVITY_MPS2


class LongitudinalSlip:
    """Decides, per odometry sample, whether the wheels slip along their travel.

    Parameters
    ----------
    window_s : float
        The window (s) over which the wheel speed change and the body's are compared.
    threshold_mps : float
        The wheels' change and its difference from the body's (m/s) that start a slip; half of it, the
        agreement between the wheel speed and the estimated speed that ends it.
    max_s : float
        Longest slip (s): then the wheels are believed again whatever they say.
    """

    def __init__(self, window_s: float, threshold_mps: float, max_s: float) -> None:
        self._window_ns = round(window_s * 1e9)
        self._threshold = threshold_mps
        self._max_ns = round(max_s * 1e9)
        # (t_ns, wheel speed m/s, the estimate's wheel speed before the sample), oldest first
        self._wheels: deque[tuple[int, float, float]] = deque()
        self._body: deque[tuple[int, float]] = deque()  # (t_ns, body acceleration m/s^2), oldest first
        self._since_ns: int | None = None
        # At a slip's start: the body's speed as the wheels would read it: the estimate at the window's
        # start (before the slipping wheels pulled it) plus the body's change of speed since.
        self.body_speed_at_start_mps = 0.0
        self._suspect = 0  # samples in a row that looked like a slip, while none is on
        self.started = 0  # slips begun
        self.timed_out = 0  # slips ended by max_s rather than by the wheels agreeing again

    @property
    def slipping(self) -> bool:
        return self._since_ns is not None

    @property
    def body_acceleration(self) -> float:
        """The newest body acceleration (m/s^2), 0.0 before the first."""
        return self._body[-1][1] if self._body else 0.0

    def add_body_acceleration(self, t_ns: int, accel_mps2: float) -> bool:
        """One IMU sample's body acceleration along its travel (gravity taken out), m/s^2; False if it was
        not taken (not after the last one, or beyond ``MAX_BODY_ACCEL_MPS2``)."""
        body = self._body
        if (body and t_ns <= body[-1][0]) or not abs(accel_mps2) <= MAX_BODY_ACCEL_MPS2:
            return False
        body.append((t_ns, accel_mps2))
        self._trim(body, t_ns)
        return True

    def body_unknown(self) -> bool:
        """The body acceleration cannot be had now (no usable pitch): the comparison waits for new samples,
        and a slip in progress ends (nothing would carry the speed); True if one did."""
        self._body.clear()
        self._suspect = 0
        was = self._since_ns is not None
        self._since_ns = None
        return was

    def judge(self, t_ns: int, wheel_speed_mps: float, estimated_wheel_speed_mps: float) -> bool:
        """Add an odometry sample and decide: True while the wheels slip.

        ``estimated_wheel_speed_mps`` is what the estimate says the wheels should read (the speed times the
        odometry scale), before this sample is fused.
        """
        wheels = self._wheels
        if wheels and t_ns <= wheels[-1][0]:
            return self.slipping
        wheels.append((t_ns, wheel_speed_mps, estimated_wheel_speed_mps))
        self._trim(wheels, t_ns)
        since = self._since_ns
        if since is not None:
            agree = abs(wheel_speed_mps - estimated_wheel_speed_mps) <= _END_SHARE * self._threshold
            if agree or t_ns - since >= self._max_ns:
                self._since_ns = None
                self.timed_out += not agree
                # The window restarts here: it held the transient just judged, which must not start
                # another slip; a new transient is judged from now on, over what of a window there is.
                while len(wheels) > 1:
                    wheels.popleft()
            return self.slipping
        _, start_wheels, start_estimate = wheels[0]
        wheel_change = wheel_speed_mps - start_wheels
        threshold = self._threshold
        # A skid or a spin is the wheels' transient: their own change must be large too. (An IMU knock or a
        # lagging pitch with the wheels steady changes the body's "change" alone, and is no slip.) Tested
        # first: the body's change, a sum over the window, is wanted only then (every control tick).
        body_change = None if abs(wheel_change) <= threshold else self._body_change(t_ns)
        if body_change is None or abs(wheel_change - body_change) <= threshold:
            self._suspect = 0
            return False
        self._suspect += 1
        if self._suspect >= _CONFIRM_SAMPLES:
            self._suspect = 0
            self._since_ns = t_ns
            self.body_speed_at_start_mps = start_estimate + body_change
            self.started += 1
        return self.slipping

    def _body_change(self, t_ns: int) -> float | None:
        """The body's change of speed (m/s) from the first wheel sample kept (the window's start, or the
        last slip's end if later) to ``t_ns``; None when the IMU does not cover that."""
        wheels, body = self._wheels, self._body
        start_ns = wheels[0][0]
        if t_ns == start_ns or not body or t_ns - body[-1][0] > _FRESH_NS:
            return None
        if body[0][0] > start_ns + _FRESH_NS:
            return None
        # The acceleration integrated over (start, t]: each sample holds from the one before it.
        change = 0.0
        previous_ns = start_ns
        for sample_ns, accel in body:
            if sample_ns <= start_ns:
                continue
            change += accel * (min(sample_ns, t_ns) - previous_ns) * 1e-9
            previous_ns = sample_ns
            if sample_ns >= t_ns:
                break
        return change

    def _trim(self, samples: deque[tuple[int, float]] | deque[tuple[int, float, float]], t_ns: int) -> None:
        """Keep one sample at or before the window's start, and the ones after it."""
        oldest = t_ns - self._window_ns
        while len(samples) > 1 and samples[1][0] <= oldest:
            samples.popleft()
