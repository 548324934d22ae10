"""Behaviour preserved: fixed-seed runs of every algorithm and sensor model give the recorded
bits (``fingerprints.json``). A change that means to alter behaviour regenerates the file on
purpose (``python -m tests.fingerprint.fingerprints --update``) and says why in its commit.

The runs are made in a child process pinned to portable numeric code paths, so the bits do not
depend on the CPU (``fingerprints.PORTABLE_ENV``); with library versions other than the
recorded ones the comparison skips and says which differ."""

from __future__ import annotations

import json
import platform
from typing import Any

import pytest

from tests.fingerprint import fingerprints as fpr

RECORD: dict[str, Any] = json.loads(fpr.JSON_PATH.read_text())
RECORDED: dict[str, dict[str, str]] = RECORD["fingerprints"]


@pytest.fixture(scope="module")
def computed() -> dict[str, dict[str, str]]:
    if platform.machine() not in fpr.PORTABLE_MACHINES:
        pytest.skip(f"fingerprints are recorded for x86-64 code paths, not {platform.machine()}")
    if diff := fpr.environment_differences(RECORD["environment"]):
        pytest.skip(
            "fingerprints were recorded with other numeric libraries or Python, which may round "
            f"differently ({'; '.join(diff)}); regenerate them with "
            "`python -m tests.fingerprint.fingerprints --update` to compare"
        )
    scenarios = [s for s in fpr.SCENARIOS if s != "fhw" or fpr.FHW.is_file()]
    return fpr.compute_portably(scenarios)


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_fixed_seed_run_gives_the_recorded_bits(
    key: str, computed: dict[str, dict[str, str]]
) -> None:
    if key.startswith("fhw/") and not fpr.FHW.is_file():
        pytest.skip(f"real log {fpr.FHW} is absent (../shared/data is not beside the project)")
    assert computed[key] == RECORDED[key]


def test_every_algorithm_and_sensor_is_recorded() -> None:
    want = {f"{s}/{m}/{a}" for s in fpr.SCENARIOS for m in fpr.SENSORS for a in fpr.ALGORITHMS}
    assert set(RECORDED) == want
    assert set(RECORD["environment"]) == {"machine", "python", *fpr.LIBRARIES}


def test_the_same_seed_gives_the_same_bits_twice() -> None:
    """Determinism on any machine and library version: two runs of one seed, bit for bit."""
    grid, log = fpr.paper_log()
    for algorithm in ("ceamcl", "mcl"):
        first = fpr.fingerprint(algorithm, "likelihood-field", grid, log)
        assert fpr.fingerprint(algorithm, "likelihood-field", grid, log) == first
