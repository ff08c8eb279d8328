"""Planning off the control thread: guidance holds (no path yet) or keeps following its last path while a
plan is in flight, takes the outcome when it is done, and drops an outcome made for an older goal."""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any, TypeVar

import numpy as np
import pytest

from navigator.config import PlannerConfig
from navigator.follower import FollowerConfig
from navigator.guidance import DRIVING, NO_PATH, PLANNING, Guidance
from navigator.perception import ObstacleObservation
from navigator.plan_worker import InlineExecutor, PlanRequest, plan_worker, run_plan_request
from navigator.planner import Planner
from navigator.terrain import TerrainMap, disc_mask
from navigator.vehicle import VehicleParams

T = TypeVar("T")


class HeldExecutor(Executor):
    """Jobs wait until the test runs them (``run_all``): a worker thread the test controls."""

    def __init__(self) -> None:
        self.queued: list[tuple[Future[Any], Callable[[], Any]]] = []

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        future: Future[T] = Future()
        self.queued.append((future, lambda: fn(*args, **kwargs)))
        return future

    def run_all(self) -> None:
        queued, self.queued = self.queued, []
        for future, job in queued:
            future.set_result(job())


def _flat(rows: int = 80, cols: int = 120, res: float = 0.25) -> TerrainMap:
    return TerrainMap(
        np.zeros((rows, cols)), np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res
    )


def _guidance(terrain: TerrainMap, executor: Executor) -> Guidance:
    return Guidance(
        terrain, VehicleParams(), PlannerConfig(sensing_range_m=40.0), FollowerConfig(), executor=executor
    )


def test_holds_until_the_first_plan_arrives_then_drives() -> None:
    worker = HeldExecutor()
    guidance = _guidance(_flat(), worker)
    guidance.set_goal(27.0, 10.0)
    out = guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    assert out.mode == PLANNING and out.speed_mps == 0.0 and guidance.planning and len(worker.queued) == 1
    assert guidance.update(1, 2.0, 10.0, 0.0, 0.0).mode == PLANNING and len(worker.queued) == 1  # one job
    worker.run_all()
    out = guidance.update(2, 2.0, 10.0, 0.0, 0.0)
    assert out.mode == DRIVING and out.path_changed and out.speed_mps > 0.0 and "planned" in out.detail
    assert not guidance.planning and guidance.replans == 1


def test_keeps_following_the_old_path_while_a_repair_is_planned() -> None:
    worker = HeldExecutor()
    guidance = _guidance(_flat(), worker)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    worker.run_all()
    first = guidance.update(1, 2.0, 10.0, 0.0, 0.0)
    assert first.path is not None
    guidance.observe([ObstacleObservation(2, "rock", 14.0, 10.0, 1.0)])  # on the path
    out = guidance.update(2, 2.0, 10.0, 0.0, 0.5)
    assert out.mode == DRIVING and out.speed_mps > 0.0 and out.path is first.path and guidance.planning
    worker.run_all()
    out = guidance.update(3, 2.0, 10.0, 0.0, 0.5)
    assert out.path_changed and out.path is not first.path and "block the path" in out.detail


def test_an_outcome_for_an_older_goal_is_dropped() -> None:
    worker = HeldExecutor()
    guidance = _guidance(_flat(), worker)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.set_goal(5.0, 17.0)  # while the first plan is in flight
    worker.run_all()
    assert guidance.update(1, 2.0, 10.0, 0.0, 0.0).mode == PLANNING  # stale: a new job for the new goal
    worker.run_all()
    out = guidance.update(2, 2.0, 10.0, 0.0, 0.0)
    assert out.path is not None and tuple(out.path.points[-1]) == (5.0, 17.0)


def test_no_path_stays_no_path_on_the_next_ticks() -> None:
    wall = np.zeros((80, 120), bool)
    wall[:, 60] = True
    walled = TerrainMap(np.zeros(wall.shape), np.zeros(wall.shape, np.uint8), wall, 0.25)
    guidance = _guidance(walled, InlineExecutor())
    guidance.set_goal(27.0, 10.0)
    assert guidance.update(0, 2.0, 10.0, 0.0, 0.0).mode == NO_PATH
    assert guidance.update(1, 2.0, 10.0, 0.0, 0.0).mode == NO_PATH  # held, not an error


@pytest.mark.realtime
def test_a_long_plan_on_the_worker_thread_does_not_block_the_tick() -> None:
    terrain = _flat(600, 600, 0.25)  # a full cost-to-go field over 360 000 cells: tens of ms at least
    with plan_worker() as worker:
        guidance = _guidance(terrain, worker)
        guidance.set_goal(145.0, 145.0)
        started = time.perf_counter()
        out = guidance.update(0, 2.0, 2.0, 0.0, 0.0)
        tick_s = time.perf_counter() - started
        assert out.mode == PLANNING
        while guidance.planning:
            out = guidance.update(1, 2.0, 2.0, 0.0, 0.0)
            time.sleep(0.001)
        plan_s = time.perf_counter() - started
    assert out.mode == DRIVING and out.path is not None
    assert tick_s < plan_s / 3, (tick_s, plan_s)


def test_obstacles_moved_off_and_new_ones_are_one_cost_update() -> None:
    """A job that takes obstacles off (moved on) and adds new ones updates the cost grid once, to the grid
    of the map as given plus the obstacles still standing, new ones included."""
    terrain = _flat()
    planner = Planner(terrain, VehicleParams())
    cart = ObstacleObservation(1, "cart-a", 10.0, 12.0, 0.6)
    rock = ObstacleObservation(2, "rock", 20.0, 6.0, 0.8)
    boulder = ObstacleObservation(3, "boulder", 14.0, 15.0, 1.0)
    run_plan_request(planner, _request(new_obstacles=(cart, rock)))
    assert planner.grid_updates == 1
    outcome = run_plan_request(
        planner, _request(new_obstacles=(boulder,), moved_off=("cart-a",), static_obstacles=(rock, boulder))
    )
    assert planner.grid_updates == 2  # one more: not a reset and then an addition
    standing = disc_mask(terrain, 20.0, 6.0, 0.8) | disc_mask(terrain, 14.0, 15.0, 1.0)
    fresh = Planner(terrain.with_obstacles(standing), VehicleParams())
    np.testing.assert_array_equal(planner.cost_grid, fresh.cost_grid)
    assert outcome.planned and outcome.path is not None and not outcome.repair_kept
    assert outcome.details[:2] == (
        "obstacles cart-a moved on: taken off the map",
        "obstacles boulder added to the map",
    )


def _request(**changes: Any) -> PlanRequest:
    fields: dict[str, Any] = dict(
        generation=0, start_xy=(2.0, 10.0), goal=(27.0, 10.0), new_obstacles=(), path=None, must_plan=False,
        retry_no_path=False,
    )  # fmt: skip
    fields.update(changes)
    return PlanRequest(**fields)


def test_a_guidance_on_new_beliefs_driving_on_follows_the_old_path_until_its_plan_arrives() -> None:
    # Learned from a slide (navigator.slide_learning): the rover is moving, so it does not stop for the plan.
    worker = HeldExecutor()
    old = _guidance(_flat(), worker)
    old.set_goal(27.0, 10.0)
    old.update(0, 2.0, 10.0, 0.0, 0.0)
    worker.run_all()
    first = old.update(1, 2.0, 10.0, 0.0, 0.0)
    assert first.path is not None
    new = _guidance(_flat(), worker)
    new.take_over_from(old)
    new.drive_on_from(old)
    out = new.update(2, 3.0, 10.0, 0.0, 0.8)
    assert out.mode == DRIVING and out.speed_mps > 0.0 and out.path is first.path and new.planning
    assert new.goal == (27.0, 10.0) and len(worker.queued) == 1  # the goal planned again, on the new beliefs
    worker.run_all()
    out = new.update(3, 3.0, 10.0, 0.0, 0.8)
    assert out.path_changed and out.path is not None and out.path is not first.path
    assert tuple(out.path.points[0]) == (3.0, 10.0)  # from where it was when the plan was asked for
