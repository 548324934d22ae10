"""``~/state``: the localisation state as a diagnostic status (level, message, values)."""

from __future__ import annotations

import pytest

from ceamcl.filters.state import LocalisationState, State

pytestmark = pytest.mark.needs_ros


@pytest.mark.parametrize(
    ("state", "level"),
    [
        (State.LOCALISED, "OK"),
        (State.AMBIGUOUS, "WARN"),
        (State.INITIALISING, "WARN"),
        (State.LOST, "ERROR"),
    ],
)
def test_state_status_levels_and_values(state: State, level: str) -> None:
    from diagnostic_msgs.msg import DiagnosticStatus

    from ceamcl.ros.messages import state_status

    n = 2 if state is State.AMBIGUOUS else 0
    weights = (0.6, 0.4) if n else ()
    msg = state_status(LocalisationState(state, 0.75, n, weights, "why"), "ceamcl", "amcl", 12.5)
    (status,) = msg.status
    assert status.level == getattr(DiagnosticStatus, level)
    assert status.message == f"{state.name}: why"
    values = {kv.key: kv.value for kv in status.values}
    assert values["state"] == state.name and values["confidence"] == "0.7500"
    assert values["n_hypotheses"] == str(n)
    assert values["weights"] == ("0.6000 0.4000" if n else "")
    assert values["map_explained"] == "nan"  # not judged
    judged = LocalisationState(state, 0.75, n, weights, "why", map_explained=0.87654)
    (status,) = state_status(judged, "ceamcl", "amcl", 12.5).status
    assert {kv.key: kv.value for kv in status.values}["map_explained"] == "0.8765"
    assert msg.header.stamp.sec == 12 and msg.header.stamp.nanosec == 500_000_000


def test_a_map_message_with_values_outside_the_range_reads_them_as_unknown() -> None:
    """Nav2's amcl reads 0 free, 100 occupied, anything else unknown; the grid refuses
    values outside -1..100, so the node maps them to unknown instead of failing on the map."""
    from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

    from ceamcl.ros.messages import grid_from_msg

    msg = OccupancyGridMsg()
    msg.info.width, msg.info.height, msg.info.resolution = 3, 1, 0.05
    msg.data = [0, 127, -100]
    assert grid_from_msg(msg).data.tolist() == [[0, -1, -1]]
