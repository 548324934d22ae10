"""Behaviour preserved: fixed-seed runs of every algorithm and sensor model give the recorded
bits (``fingerprints.json``). A change that means to alter behaviour regenerates the file on
purpose (``python -m tests.fingerprint.fingerprints --update``) and says why in its commit."""

from __future__ import annotations

import json
from typing import Any

import pytest

from tests.fingerprint import fingerprints as fpr

RECORDED: dict[str, dict[str, str]] = json.loads(fpr.JSON_PATH.read_text())


@pytest.fixture(scope="module")
def paper() -> tuple[Any, Any]:
    return fpr.paper_log()


@pytest.fixture(scope="module")
def fhw() -> tuple[Any, Any]:
    if not fpr.FHW.is_file():
        pytest.skip(f"real log {fpr.FHW} is absent (../shared/data is not beside the project)")
    return fpr.fhw_log()


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_fixed_seed_run_gives_the_recorded_bits(key: str, request: pytest.FixtureRequest) -> None:
    scenario, sensor, algorithm = key.split("/")
    grid, log = request.getfixturevalue(scenario)
    assert fpr.fingerprint(algorithm, sensor, grid, log) == RECORDED[key]


def test_every_algorithm_and_sensor_is_recorded() -> None:
    want = {f"{s}/{m}/{a}" for s in fpr.SCENARIOS for m in fpr.SENSORS for a in fpr.ALGORITHMS}
    assert set(RECORDED) == want
