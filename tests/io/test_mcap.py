"""Tests of ``ceamcl.io.mcap_export``: the MCAP file read back with the ``mcap`` reader."""

from __future__ import annotations

import base64
import dataclasses
import json
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from ceamcl.io.mcap_export import SCHEMAS, time_ns, write_mcap
from tests.viz.runs import SNAPSHOT_EVERY, STEPS, short_run

ALL_TOPICS = {
    "/map": "foxglove.Grid",
    "/particles": "foxglove.PosesInFrame",
    "/estimate": "foxglove.PoseInFrame",
    "/ground_truth": "foxglove.PoseInFrame",
    "/scan": "foxglove.LaserScan",
    "/tf": "foxglove.FrameTransforms",
    "/state": "ceamcl.LocalisationState",
}


def _read(path: Path) -> tuple[Any, dict[str, list[tuple[int, dict[str, Any]]]]]:
    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        messages: dict[str, list[tuple[int, dict[str, Any]]]] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            assert schema is not None
            assert schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            decoded = json.loads(message.data)
            body = json.loads(schema.data)
            jsonschema.validate(decoded, body)
            _only_known_fields(decoded, body, channel.topic)
            messages.setdefault(channel.topic, []).append((message.log_time, decoded))
    return summary, messages


def _only_known_fields(value: Any, schema: dict[str, Any], where: str) -> None:
    """Every key of the message is a field of the schema (Foxglove ignores unknown ones)."""
    if schema.get("type") == "object" and isinstance(value, dict):
        props = schema["properties"]
        assert set(value) <= set(props), f"{where}: unknown fields {set(value) - set(props)}"
        for key, item in value.items():
            _only_known_fields(item, props[key], f"{where}.{key}")
    elif schema.get("type") == "array" and isinstance(value, list):
        for item in value:
            _only_known_fields(item, schema["items"], f"{where}[]")


def _yaw(q: dict[str, float]) -> float:
    assert q["x"] == 0.0 and q["y"] == 0.0
    return float(2.0 * np.arctan2(q["z"], q["w"]))


def _xy_yaw(pose: dict[str, Any]) -> list[float]:
    return [pose["position"]["x"], pose["position"]["y"], _yaw(pose["orientation"])]


def _wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * np.asarray(a)))


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, dict[str, Any]]:
    result, grid, log = short_run()
    path = write_mcap(tmp_path_factory.mktemp("mcap") / "run.mcap", result, grid, log)
    assert [p.name for p in path.parent.iterdir()] == ["run.mcap"]
    return _read(path)


def test_channels_and_schemas_are_foxgloves(exported: tuple[Any, dict[str, Any]]) -> None:
    summary, _ = exported
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert topics == ALL_TOPICS
    for schema in summary.schemas.values():
        body = json.loads(schema.data)
        assert body["title"] == schema.name
        # Foxglove's own schemas, and ours for the state (shown in its Raw Messages panel)
        assert schema.name.startswith("foxglove.") or schema.name == "ceamcl.LocalisationState"


def test_message_counts(exported: tuple[Any, dict[str, Any]]) -> None:
    summary, messages = exported
    result, _, _ = short_run()
    kept = sorted({0, STEPS - 1, *result.snapshots})
    expected = {
        "/map": 1,
        "/particles": len(kept),
        "/estimate": STEPS,
        "/ground_truth": STEPS,
        "/scan": STEPS,
        "/tf": STEPS,
        "/state": STEPS,
    }
    assert {t: len(m) for t, m in messages.items()} == expected
    counts = summary.statistics.channel_message_counts
    by_topic = {summary.channels[cid].topic: n for cid, n in counts.items()}
    assert by_topic == expected
    assert len(kept) == len(range(0, STEPS, SNAPSHOT_EVERY))


def test_timestamps_are_the_log_times(exported: tuple[Any, dict[str, Any]]) -> None:
    _, messages = exported
    result, _, _ = short_run()
    ns = [time_ns(t) for t in result.times]
    for topic in ("/estimate", "/ground_truth", "/scan"):
        assert [t for t, _ in messages[topic]] == ns
        for t, m in messages[topic]:
            assert m["timestamp"] == {"sec": t // 10**9, "nsec": t % 10**9}
    assert [t for t, _ in messages["/particles"]] == [ns[k] for k in sorted(result.snapshots)]


def test_poses_decode_to_the_run(exported: tuple[Any, dict[str, Any]]) -> None:
    _, messages = exported
    result, _, _ = short_run()
    assert result.truth is not None
    for topic, expected in (("/estimate", result.estimates), ("/ground_truth", result.truth)):
        got = np.array([_xy_yaw(m["pose"]) for _, m in messages[topic]])
        assert {m["frame_id"] for _, m in messages[topic]} == {"map"}
        np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-12)
        np.testing.assert_allclose(_wrapped(got[:, 2] - expected[:, 2]), 0.0, atol=1e-9)
    for (_, m), k in zip(messages["/particles"], sorted(result.snapshots), strict=True):
        poses = np.array([_xy_yaw(p) for p in m["poses"]])
        snap = result.snapshots[k].poses
        assert poses.shape == snap.shape
        # particles are rounded to 0.1 mm and ~1e-6 rad
        np.testing.assert_allclose(poses[:, :2], snap[:, :2], atol=0.51e-4)
        np.testing.assert_allclose(_wrapped(poses[:, 2] - snap[:, 2]), 0.0, atol=1e-5)


def test_scans_and_transforms(exported: tuple[Any, dict[str, Any]]) -> None:
    _, messages = exported
    result, _, log = short_run()
    assert result.truth is not None
    for k, (_, m) in enumerate(messages["/scan"]):
        scan = log.scan(k)
        assert m["frame_id"] == "laser"
        np.testing.assert_allclose(m["ranges"], scan.ranges)
        assert m["start_angle"] == pytest.approx(scan.angle_min)
        assert m["end_angle"] == pytest.approx(scan.angles[-1])
    for k, (_, m) in enumerate(messages["/tf"]):
        to_base, to_laser = m["transforms"]
        assert (to_base["parent_frame_id"], to_base["child_frame_id"]) == ("map", "base_link")
        assert (to_laser["parent_frame_id"], to_laser["child_frame_id"]) == ("base_link", "laser")
        t = to_base["translation"]
        np.testing.assert_allclose([t["x"], t["y"]], result.truth[k, :2], atol=1e-12)
        assert to_laser["translation"]["x"] == pytest.approx(log.laser.pose[0])


def test_map_grid_decodes_to_the_occupancy_grid(exported: tuple[Any, dict[str, Any]]) -> None:
    _, messages = exported
    _, grid, _ = short_run()
    ((_, m),) = messages["/map"]
    assert m["column_count"] == grid.width
    assert m["cell_size"] == {"x": grid.resolution, "y": grid.resolution}
    fields = {f["name"]: f for f in m["fields"]}
    assert {"red", "green", "blue", "alpha", "occupancy"} <= set(fields)
    raw = np.frombuffer(base64.b64decode(m["data"]), dtype=np.uint8)
    assert raw.size == m["row_stride"] * grid.height
    cells = raw.reshape(grid.height, grid.width, m["cell_stride"])
    occupancy = cells[..., fields["occupancy"]["offset"]].view(np.int8)
    np.testing.assert_array_equal(occupancy, grid.data)
    red = cells[..., fields["red"]["offset"]]
    assert np.all(red[grid.occupied_mask] == 0) and np.all(red[grid.free_mask] == 255)


def test_without_truth_or_log_the_base_frame_follows_the_estimate(tmp_path: Path) -> None:
    result, grid, _ = short_run()
    blind = dataclasses.replace(result, truth=None, snapshots={})
    _, messages = _read(write_mcap(tmp_path / "x.mcap", blind, grid))
    assert set(messages) == {"/map", "/particles", "/estimate", "/tf", "/state"}
    assert len(messages["/particles"]) == 2  # first and last step
    for k, (_, m) in enumerate(messages["/tf"]):
        t = m["transforms"][0]["translation"]
        np.testing.assert_allclose([t["x"], t["y"]], result.estimates[k, :2], atol=1e-12)


def test_log_of_another_length_is_refused(tmp_path: Path) -> None:
    result, grid, _ = short_run()
    _, _, other = short_run("mcl")
    shorter = dataclasses.replace(result, times=result.times[:5])
    with pytest.raises(ValueError, match="log has"):
        write_mcap(tmp_path / "x.mcap", shorter, grid, other)
    assert not list(tmp_path.iterdir())


def test_schemas_are_valid_json_schemas() -> None:
    for name in (
        "foxglove.Grid",
        "foxglove.PosesInFrame",
        "foxglove.PoseInFrame",
        "foxglove.LaserScan",
        "foxglove.FrameTransforms",
        "ceamcl.LocalisationState",
    ):
        schema = SCHEMAS[name]
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["title"] == name


def test_the_state_of_every_step_is_exported(exported: tuple[Any, dict[str, Any]]) -> None:
    _, messages = exported
    states = messages["/state"]
    assert len(states) == STEPS
    assert states[0][1]["state"] == "INITIALISING"
    assert {m["state"] for _, m in states} <= {"LOCALISED", "AMBIGUOUS", "LOST", "INITIALISING"}
    assert all(0.0 <= m["confidence"] <= 1.0 and m["reason"] for _, m in states)
    assert all(len(m["weights"]) == m["n_hypotheses"] for _, m in states)
    # the map's share of the scan: null before the first update, a share once it is judged
    assert states[0][1]["map_explained"] is None
    shares = [m["map_explained"] for _, m in states[1:]]
    assert shares and all(x is None or 0.0 <= x <= 1.0 for x in shares)
    assert any(x is not None for x in shares)
