"""Which scenario faults a trial ran in full, and how long a trial parks after ARRIVED for the rest."""

from __future__ import annotations

from hil.fault_coverage import park_until_ns, unexercised_faults
from hil.faults import Fault

S = 1_000_000_000
TRIAL_END = 45 * S
UNTIL_THE_END = TRIAL_END + S  # what hil.faults gives a fault written without duration_s


def gps_off(start_s: float, end_ns: int) -> Fault:
    return Fault("gps", "off", round(start_s * S), end_ns)


def test_no_fault_left_to_run_stops_at_the_arrival() -> None:
    assert park_until_ns([], 18 * S, TRIAL_END) == 18 * S
    assert park_until_ns([gps_off(5.0, 10 * S)], 18 * S, TRIAL_END) == 18 * S
    # Started before the arrival and lasting until the end: the trial's end is its end, it ran.
    assert park_until_ns([gps_off(5.0, UNTIL_THE_END)], 18 * S, TRIAL_END) == 18 * S


def test_a_fault_still_to_run_keeps_the_trial_going_until_its_end() -> None:
    assert park_until_ns([gps_off(30.0, 35 * S)], 18 * S, TRIAL_END) == 35 * S
    assert park_until_ns([gps_off(10.0, 20 * S), gps_off(25.0, 27 * S)], 18 * S, TRIAL_END) == 27 * S


def test_a_fault_until_the_end_that_starts_after_the_arrival_runs_until_the_scenarios_duration() -> None:
    assert park_until_ns([gps_off(30.0, UNTIL_THE_END)], 18 * S, TRIAL_END) == TRIAL_END


def test_parking_never_outlasts_the_scenario() -> None:
    assert park_until_ns([gps_off(30.0, 60 * S)], 18 * S, TRIAL_END) == TRIAL_END


def test_faults_run_in_full_are_not_named() -> None:
    faults = [gps_off(5.0, 10 * S), gps_off(12.0, UNTIL_THE_END)]
    assert unexercised_faults(faults, 18 * S, TRIAL_END, "arrived", 18 * S) == []


def test_a_fault_that_never_started_is_named_with_how_the_trial_ended() -> None:
    (failure,) = unexercised_faults(
        [gps_off(30.0, 35 * S)], int(18.2 * S), TRIAL_END, "arrived", int(18.2 * S)
    )
    assert failure == "fault gps/off at 30.0 s never ran: the trial ended at ARRIVED at 18.2 s"


def test_a_fault_cut_short_is_named() -> None:
    (failure,) = unexercised_faults([gps_off(1.0, 40 * S)], 2 * S, TRIAL_END, "no_path", None)
    assert failure == (
        "fault gps/off from 1.0 s to 40.0 s was cut short: "
        "the trial ended at NO_PATH (the planner found no path to the goal) at 2.0 s"
    )
    (failure,) = unexercised_faults([gps_off(1.0, 40 * S)], 9 * S, TRIAL_END, "rollover", None)
    assert failure.endswith("cut short: the trial ended at a rollover at 9.0 s")


def test_a_rollover_before_a_fault_until_the_end_began_names_it() -> None:
    (failure,) = unexercised_faults([gps_off(30.0, UNTIL_THE_END)], 9 * S, TRIAL_END, "rollover", None)
    assert failure == "fault gps/off at 30.0 s never ran: the trial ended at a rollover at 9.0 s"


def test_a_fault_the_scenarios_duration_leaves_no_time_for_is_named() -> None:
    # The scenario loader refuses such a fault; a Scenario built in code can still hold one.
    (failure,) = unexercised_faults([gps_off(45.0, 50 * S)], TRIAL_END, TRIAL_END, "timeout", None)
    assert failure == "fault gps/off at 45.0 s never ran: the trial ended at its duration_s, 45.0 s"
    (failure,) = unexercised_faults([gps_off(46.0, 50 * S)], TRIAL_END, TRIAL_END, "arrived", 18 * S)
    assert failure.endswith("never ran: the trial ended at 45.0 s, parked since ARRIVED at 18.0 s")
