"""Making a test-case (an ego alone on a junction, its start and duration checked) and
loading the intersection a test-case was made on, under its signal program."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from service.core import names
from service.core.errors import InvalidInput, InvalidTestCase
from service.core.motion.kinematics import fastest
from service.core.motion.poses import (
    check_start_speed,
    longest_start,
    plan_drive,
    start_speed_limit,
)
from service.core.network import (
    Intersection,
    Route,
    SignalProgram,
    load_intersection,
    with_signals,
)
from service.core.testcase.document import parse_testcase
from service.core.testcase.model import SCHEMA, Params, TestCase
from service.core.testcase.network_path import find_network_file, network_ref

DEFAULT_START_DISTANCE = names.DEFAULT_START_DISTANCE  # m: the ego's automatic start
DEFAULT_START_SPEED = names.DEFAULT_START_SPEED  # m/s: its speed (both in service.core.names)


def new_testcase(
    network: str | Path,
    ego_route: str,
    junction: str | None = None,
    control: str | None = None,
    start_distance: float | None = None,
    start_speed: float | None = None,
    duration: float = 20.0,
    timestep: float = 0.1,
    params: Params | None = None,
    cache_dir: Path | None = None,
    name: str = "",
    major_road: Sequence[str] | None = None,
    signals: SignalProgram | None = None,
    guess_crossings: bool = False,
) -> TestCase:
    """An ego-only test-case; checks that the route exists and the start lies on the map.

    ``start_distance`` None is automatic: DEFAULT_START_DISTANCE, or the whole road before
    the fork where it is shorter (a start given is refused when the road is shorter).
    ``start_speed`` None is automatic: DEFAULT_START_SPEED, or the speed limit of the lane
    the ego starts on (or v_max) where that is lower; a speed given above either is refused.
    ``major_road``: two roads into a priority_stop or priority junction that keep the right
    of way (service.core.network.load_intersection); the test-case keeps it
    (``major_road``), so every later command rebuilds the same network. ``signals``: the
    program of a signalized junction (default: the network's, when it is fixed-time); the
    test-case carries it.
    ``guess_crossings``: the network gets sidewalks and crossings (netconvert guesses them;
    the route's lane indices are those of the rebuilt network); the test-case keeps it
    (``crossings_guessed``) like ``major_road``."""
    intersection = load_intersection(
        network,
        junction,
        control,
        cache_dir,
        major_road=major_road,
        guess_crossings=guess_crossings,
    )
    intersection = _signalled(intersection, signals)
    route = intersection.route(ego_route)
    _check_ego_can_go(intersection, route, duration)
    chosen = params or Params()
    if start_speed is not None and start_speed > chosen.v_max:
        raise InvalidTestCase(
            f"ego start speed {start_speed:g} m/s exceeds v_max {chosen.v_max:g} m/s"
        )
    speed = min(DEFAULT_START_SPEED, chosen.v_max) if start_speed is None else start_speed
    if start_distance is None:
        start_distance = longest_start(intersection, route, DEFAULT_START_DISTANCE)
    document: dict[str, Any] = {
        "schema": SCHEMA,
        "name": name,
        "network": network_ref(network).model_dump(),
        "junction": intersection.junction,
        "control": intersection.control.value,
        "rules": intersection.control.rule_set,
        "timestep": timestep,
        "duration": duration,
        "params": chosen.model_dump(),
        "ego": {
            "route": {"fork": route.fork, "exit": route.exit},
            "start": {"distance": start_distance, "speed": speed},
        },
    }
    if major_road is not None:
        document["major_road"] = list(major_road)
    if guess_crossings:
        document["crossings_guessed"] = True
    if intersection.signals is not None:
        document["signals"] = intersection.signals.to_document()
    testcase = parse_testcase(document)
    # Fails with a clear message when the start lies beyond the mapped road.
    plan = plan_drive(intersection, route, start_distance, max(speed, 1.0), duration, timestep)
    fork = intersection.forks[route.fork]
    stop_at = start_distance + fork.limit_offset if fork.stop_sign else None
    _check_ego_can_arrive(plan.leave_distance, speed, chosen, duration, start_distance, stop_at)
    if start_speed is not None:
        check_start_speed(intersection, plan, start_speed)
    elif speed > start_speed_limit(intersection, plan):
        document["ego"]["start"]["speed"] = start_speed_limit(intersection, plan)
        testcase = parse_testcase(document)
    return testcase


def load_testcase_intersection(
    testcase: TestCase,
    cache_dir: Path | None = None,
    network_file: Path | None = None,
    near: Path | None = None,
) -> Intersection:
    """The intersection of a test-case, after checking that its network is unchanged
    (``find_network_file``: ``network_file`` stands in for the reference, for example when
    the test-case names a network that only a server knows; ``near`` is the folder the
    test-case was read from)."""
    path, _ = find_network_file(testcase, network_file, near)
    intersection = load_intersection(
        path,
        testcase.junction,
        testcase.control,
        cache_dir,
        major_road=testcase.major_road,
        guess_crossings=testcase.crossings_guessed,
    )
    return under_testcase_signals(intersection, testcase)


def under_testcase_signals(intersection: Intersection, testcase: TestCase) -> Intersection:
    """``intersection`` under the test-case's signal program (the one it carries, not the
    network's); InvalidTestCase when the program does not fit the junction."""
    if testcase.signals is None:
        return intersection
    try:
        return with_signals(intersection, testcase.signals.to_program())
    except InvalidInput as exc:
        raise InvalidTestCase(f"signals: {exc}") from None


def _check_ego_can_go(intersection: Intersection, route: Route, duration: float) -> None:
    """InvalidInput when the ego's signal shows red for the whole test-case: no ego could
    pass it lawfully, so the test-case would have no solution to make harder."""
    program = intersection.signals
    if program is None or route.link_index < 0 or program.goes_within(route.link_index, duration):
        return
    go = program.first_go(route.link_index)
    when = "never shows a colour to go" if go is None else f"first lets it go at {go:g} s"
    raise InvalidInput(
        f"the ego's signal (link {route.link_index} of traffic light {program.tls!r}) is red "
        f"for the whole test-case ({duration:g} s) and {when}: no ego could pass it; give "
        "a longer duration, another ego route, or a program with another offset (--signals; "
        "the API's signals field)"
    )


def _check_ego_can_arrive(
    distance: float, speed: float, params: Params, duration: float, start_distance: float,
    stop_at: float | None,
) -> None:  # fmt: skip
    """InvalidInput when the ego cannot reach its goal (its back out of the junction,
    ``distance`` metres from its start) within ``duration`` even at full speed: from its
    start speed, accelerating at a_max up to v_max, braking at a_min, stopping only where
    it must: at a stop sign, before the junction's entry ``stop_at`` metres from its start
    (at v_stop or below; None: no sign). No ego could pass such a test-case, so no harder
    one exists; the message names the shortest duration in which one could (a lower bound:
    a red light or the traffic add to it)."""
    least = fastest(distance, speed, params.a_max, params.v_max)
    how = "never stopping"
    if stop_at is not None:  # it slows to v_stop somewhere before stop_at, then goes on
        braking = max(0.0, speed - params.v_stop) / -params.a_min
        going = fastest(distance - stop_at, params.v_stop, params.a_max, params.v_max)
        least = max(least, braking + going)
        how = "stopping only at the stop sign, for no time"
    if least <= duration:
        return
    shortest = math.ceil(least * 10) / 10
    raise InvalidInput(
        f"duration {duration:g} s is too short for the ego to reach its exit: from its start "
        f"{start_distance:g} m before the stop line it drives {distance:.1f} m to leave the "
        f"junction, which takes at least {least:.2f} s even at full speed (a_max "
        f"{params.a_max:g} m/s², a_min {params.a_min:g} m/s², v_max {params.v_max:g} m/s, "
        f"{how}); give a duration of {shortest:g} s or more (more where it must wait), or a "
        "shorter start distance"
    )


def _signalled(intersection: Intersection, signals: SignalProgram | None) -> Intersection:
    """The intersection under the program given, or its network's; InvalidInput when a
    signalized junction has no fixed-time program, or a program is given to another."""
    if signals is not None:
        return with_signals(intersection, signals)
    if intersection.control.signalized and intersection.signals is None:
        raise InvalidInput(intersection.signals_refused or "the junction has no signal program")
    return intersection
