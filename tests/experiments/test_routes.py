"""Courses: the built-in protocols, and route files beside a user's ROS map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl import budget
from ceamcl.errors import CeamclError, ConfigError
from ceamcl.experiments.routes import (
    kidnapped_course,
    load_route_file,
    paper_course,
    resolve_course,
)
from ceamcl.maps.ros_io import save_map
from ceamcl.maps.worlds import get_world, symmetric_images
from ceamcl.simulation.scenarios import paper_scenario


def test_paper_course_has_the_four_rooms_and_the_hall_images() -> None:
    course = paper_course("symmetric-hall")
    assert [r.name for r in course.routes] == ["room0", "room1", "room2", "room3"]
    for room, route in enumerate(course.routes):
        assert np.allclose(route.start, paper_scenario(room).start)
    pose = np.array([2.0, 5.0, 0.7])
    assert np.allclose(course.images(pose), symmetric_images(pose))


def test_built_in_courses_by_experiment() -> None:
    assert resolve_course("marked", None, None).world == "marked-hall"
    assert resolve_course("table1", None, None).world == "symmetric-hall"
    kid = resolve_course("kidnapped", None, None)
    assert kid.world == "small-office" and kid.n_images == 1
    assert kid.routes[0].kidnap is not None
    with pytest.raises(ConfigError, match="small-office"):
        resolve_course("table1", "small-office", None)


def _hall_map(tmp_path: Path) -> Path:
    return save_map(get_world("symmetric-hall"), tmp_path / "hall.yaml")


def test_route_file_reproduces_the_paper_course(tmp_path: Path) -> None:
    _hall_map(tmp_path)
    (tmp_path / "routes.yaml").write_text(
        """
map: hall.yaml
routes:
  - name: sw
    start: [3.75, 3.75, 1.5707963]
    waypoints: [[3.75, 6.6], [3.75, 8.4], [6.6, 14.1, -2.3561945]]
symmetry:
  rotations: 4
  centre: [7.5, 7.5]
simulation:
  rate_hz: 5
"""
    )
    course = load_route_file(tmp_path / "routes.yaml")
    assert course.map_path is not None and course.world is None
    assert course.config.rate_hz == 5
    pose = np.array([1.0, 2.0, -0.3])
    assert np.allclose(course.images(pose), symmetric_images(pose))
    grid = course.grid()
    assert grid.width == get_world("symmetric-hall").width
    path = course.scenario(0).true_path()
    assert np.allclose(path[0], [3.75, 3.75, np.pi / 2])


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("map: hall.yaml\nroutes: []\n", "routes"),
        (
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75]\n    waypoints: [[3, 3]]\n",
            r"routes\[0\]\.start",
        ),
        (
            "map: hall.yaml\nroutes:\n  - start: [0.0, 0.0, 0]\n    waypoints: [[3, 3]]\n",
            "not in free space",
        ),
        (
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "    speed: 2\n",
            r"routes\[0\]\.speed",
        ),
        (
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "symmetry: {rotations: 4}\n",
            "symmetry.centre",
        ),
        ("map: hall.yaml\nroute: []\n", "route"),
        (  # the tables group runs by name: two routes of one name were pooled
            "map: hall.yaml\nroutes:\n  - name: a\n    start: [3.75, 3.75, 0]\n"
            "    waypoints: [[3, 3]]\n  - name: a\n    start: [3.75, 3.75, 0]\n"
            "    waypoints: [[3, 3]]\n",
            r"routes\[1\]\.name: 'a' is routes\[0\]'s name too",
        ),
        (
            "map: hall.yaml\nroutes:\n  - name: all\n    start: [3.75, 3.75, 0]\n"
            "    waypoints: [[3, 3]]\n",
            r"routes\[0\]\.name: 'all' names the tables' row over every route",
        ),
        (  # a kidnap's waypoints are checked as a route's (one off the map was driven to)
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "    kidnap: {at_s: 5, pose: [3.75, 3.75, 0], waypoints: [[3, 3], [40, 3]]}\n",
            r"routes\[0\]\.kidnap\.waypoints\[1\]",
        ),
        (  # infinite or NaN simulation settings divided by zero or emptied the scans
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "simulation: {rate_hz: .inf}\n",
            "rate_hz: expected a finite number > 0",
        ),
        (
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "simulation: {range_sigma_m: .nan}\n",
            "range_sigma_m: expected a finite number >= 0",
        ),
        (
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
            "simulation: {speed_mps: true}\n",
            r"simulation\.speed_mps: expected a number, got True",
        ),
        (  # one step, the initialisation, reported as the run's step time
            "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 1.5708]\n"
            "    waypoints: [[3.75, 3.75], [3.75, 3.75, 1.5708]]\n",
            r"routes\[0\]\.waypoints: the route does not move",
        ),
    ],
)
def test_bad_route_files_name_the_field(tmp_path: Path, body: str, field: str) -> None:
    _hall_map(tmp_path)
    f = tmp_path / "bad.yaml"
    f.write_text(body)
    with pytest.raises(ConfigError, match=field) as info:
        load_route_file(f)
    assert "bad.yaml" in str(info.value)


def test_a_budget_refusal_writes_a_huge_count_compactly(tmp_path: Path) -> None:
    """A turn rate of 1e-300 rad/s asks for 6.3e+301 steps: the refusal printed all 302 of
    its digits (an 859-character line); it is one short line."""
    _hall_map(tmp_path)
    f = tmp_path / "slow.yaml"
    f.write_text(
        "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
        "simulation:\n  turn_rate_rps: 1e-300\n"
    )
    with pytest.raises(
        budget.BudgetError, match=r"routes\[0\] .*: 6\.3e\+301 steps would need "
    ) as info:
        load_route_file(f)
    assert len(str(info.value)) < 250
    assert budget.format_count(124_021_032) == "124,021,032"
    assert budget.format_count(float("inf")) == "inf"
    assert budget.format_bytes(7.4 * (1 << 30)) == "7.4 GiB"
    assert budget.format_bytes(1e306) == "1.0e+306 B"


def test_a_repeated_key_in_a_route_file_is_refused(tmp_path: Path) -> None:
    """Two 'routes:' keys loaded only the second list, silently."""
    _hall_map(tmp_path)
    f = tmp_path / "twice.yaml"
    route = "  - start: [3.75, 3.75, 0]\n    waypoints: [[3, 3]]\n"
    f.write_text(f"map: hall.yaml\nroutes:\n{route}routes:\n{route}")
    with pytest.raises(ConfigError, match=r"twice\.yaml:5: .*duplicate key 'routes' \(first on"):
        load_route_file(f)


def test_a_route_that_only_turns_on_the_spot_moves(tmp_path: Path) -> None:
    _hall_map(tmp_path)
    f = tmp_path / "turn.yaml"
    f.write_text(
        "map: hall.yaml\nroutes:\n  - start: [3.75, 3.75, 0]\n    waypoints: [[3.75, 3.75, 1]]\n"
    )
    assert len(load_route_file(f).routes) == 1


def test_missing_route_file_and_map(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_route_file(tmp_path / "nope.yaml")
    f = tmp_path / "r.yaml"
    f.write_text("map: missing.yaml\nroutes:\n  - start: [1, 1, 0]\n    waypoints: [[2, 2]]\n")
    with pytest.raises(CeamclError, match=r"missing\.yaml"):
        load_route_file(f)


def test_select_starts() -> None:
    course = paper_course().select([2, 0])
    assert [r.name for r in course.routes] == ["room2", "room0"]
    with pytest.raises(ConfigError, match="start-routes: route 4 out of range"):
        paper_course().select([4])
    with pytest.raises(ConfigError, match="start-routes: expected one or more route numbers"):
        paper_course().select([])  # ran no route: empty tables, or a traceback


def test_kidnapped_course_jumps_while_odometry_stands_still() -> None:
    course = kidnapped_course()
    sc = course.scenario(0)
    log = sc.simulate(np.random.default_rng(3), course.grid())
    (k,) = log.kidnapped_at
    assert sc.kidnap is not None
    assert np.isclose(log.times[k], sc.kidnap.at_s)
    assert np.hypot(*(log.true_poses[k, :2] - log.true_poses[k - 1, :2])) > 2.0
    assert np.array_equal(log.odometry[k], log.odometry[k - 1])
    assert np.allclose(log.true_poses[k], sc.kidnap.pose)


def test_a_chosen_route_keeps_its_seed() -> None:
    """``--start-routes 1`` runs room 1 as it runs among all four routes (its number is its
    seed key), and a route given twice is refused."""
    from ceamcl.experiments.trials import Trial, simulate_trial_log

    full, one = paper_course(), paper_course().select([1])
    assert one.number(0) == 1 and full.number(1) == 1
    a = Trial("table1", "mcl", full, 1, 0, 7, max_time_s=2.0)
    b = Trial("table1", "mcl", one, 0, 0, 7, max_time_s=2.0)
    assert a.route == b.route == "room1" and b.route_number == 1
    la, lb = simulate_trial_log(a), simulate_trial_log(b)
    np.testing.assert_array_equal(la.odometry, lb.odometry)
    np.testing.assert_array_equal(la.true_poses, lb.true_poses)
    with pytest.raises(ConfigError, match="start-routes: route 2 given twice"):
        paper_course().select([2, 0, 2])
