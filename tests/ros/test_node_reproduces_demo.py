"""The node adds nothing but transport: its core (``ceamcl.ros.localiser.Localiser``, what the
node process runs on every converted message), given the demo's run and the demo's settings,
ends with exactly the hypotheses of ``ceamcl demo`` with the same seed (no ROS needed).

The settings that make a node run a demo: ``seed`` (the node draws the filter's stream of
``ceamcl demo --seed S``), ``update_min_d = update_min_a = 0`` (the demo updates at every scan,
Nav2 every 0.25 m / 0.2 rad), and the demo's likelihood field, ``z_hit 0.95`` and ``z_rand 0.05``
(Nav2's defaults are 0.5 and 0.5). Through DDS the ranges travel as float32: from there on the
run differs in its random choices, and ends with the same four hypotheses, 0.018-0.042 m from the
demo's and with weights within 0.01 (seeds 0-4, measured), though which of the four near-equal
images leads may differ; ``test_node_hall.py`` checks the node process' four hypotheses.
"""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.demo import run_demo, seeded_generators
from ceamcl.maps.worlds import symmetric_images
from ceamcl.ros.localiser import Localiser, cap_notice, sensor_model
from ceamcl.ros.params import parse
from ceamcl.simulation.scenarios import get_scenario

DEMO_SETTINGS = {"update_min_d": 0.0, "update_min_a": 0.0, "z_hit": 0.95, "z_rand": 0.05}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_node_core_reproduces_ceamcl_demo_bit_for_bit(seed: int) -> None:
    node, expected = run_node_core(seed, float32=False)
    assert node.shape == expected.shape == (4, 5)  # the four symmetric images
    np.testing.assert_array_equal(node, expected)


def run_node_core(seed: int, float32: bool) -> tuple[np.ndarray, np.ndarray]:
    demo = run_demo("ceamcl", world="symmetric-hall", seed=seed)
    scenario = get_scenario("paper", "symmetric-hall", 0)
    grid = scenario.grid()
    log = scenario.simulate(seeded_generators(seed, 2)[0], grid)
    if float32:  # as sensor_msgs/LaserScan carries them
        log.ranges[:] = np.asarray(log.ranges, dtype=np.float32)
    localiser = Localiser(parse({"seed": seed, **DEMO_SETTINGS}))
    localiser.set_map(grid)
    for k in range(len(log)):
        localiser.scan(tuple(log.odometry[k]), log.scan(k))
    assert localiser.filter is not None
    node = np.array([[*h.pose, h.weight, h.fitness] for h in localiser.filter.hypotheses()])
    return node, demo.result.hypotheses[-1]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_float32_scans_give_the_demos_hypotheses_to_rounding(seed: int) -> None:
    node, expected = run_node_core(seed, float32=True)
    assert node.shape == expected.shape == (4, 5)
    for h in node:
        nearest = int(np.argmin(np.hypot(*(expected[:, :2] - h[:2]).T)))
        assert np.hypot(*(expected[nearest, :2] - h[:2])) < 0.1
        assert abs(expected[nearest, 3] - h[3]) < 0.03


def test_laser_temper_reaches_the_sensor_model() -> None:
    grid = get_scenario("paper", "symmetric-hall", 0).grid()
    assert sensor_model(parse({}), grid).temper == pytest.approx(0.2)
    assert sensor_model(parse({"laser_temper": 0.5}), grid).temper == pytest.approx(0.5)
    beam = parse({"laser_temper": 0.1, "laser_model_type": "beam"})
    assert sensor_model(beam, grid).temper == pytest.approx(0.1)


@pytest.mark.parametrize("value", [0.0, -0.2, 1.5, float("nan"), "high", True])
def test_a_bad_laser_temper_is_named(value: object) -> None:
    from ceamcl.errors import ConfigError

    with pytest.raises(ConfigError, match="laser_temper: expected a number in"):
        parse({"laser_temper": value})


def test_amcls_scoring_takes_no_laser_temper() -> None:
    from ceamcl.errors import ConfigError

    grid = get_scenario("paper", "symmetric-hall", 0).grid()
    kld = parse({"algorithm": "kld-amcl"})  # unset: the scoring's own default (none)
    assert sensor_model(kld, grid).temper == pytest.approx(0.2)  # the product's, replaced below
    Localiser(kld).set_map(grid)  # builds the filter with amcl's scoring
    with pytest.raises(ConfigError, match="laser_temper: kld-amcl scores scans as amcl does"):
        parse({"algorithm": "kld-amcl", "laser_temper": 0.5})


def test_max_particles_caps_ceamcls_sample_size() -> None:
    """CEAMCL sizes its species itself (eq. 5); in the node Nav2's ``max_particles`` caps
    their total, as it caps Nav2's filter. The demo's run holds 369 samples at the first scan
    and up to 421 (seed 0); with a budget of 200 no update holds more, the node says that the
    first search wanted more, and the four images are still held at the end."""
    scenario = get_scenario("paper", "symmetric-hall", 0)
    grid = scenario.grid()
    log = scenario.simulate(seeded_generators(0, 2)[0], grid)
    budget = {"max_particles": 200, "min_particles": 100}
    localiser = Localiser(parse({"seed": 0, **DEMO_SETTINGS, **budget}))
    localiser.set_map(grid)
    held, notices = [], []
    for k in range(len(log)):
        localiser.scan(tuple(log.odometry[k]), log.scan(k))
        assert localiser.filter is not None
        held.append(localiser.filter.particle_weights().size)
        notices.append(cap_notice(localiser.filter))  # every scan updates here
    assert max(held) <= 200
    # the first search wanted more (369): the node logs it, once, naming the cap
    assert notices[0] is not None and "cap of 200" in notices[0]
    assert notices[1:] == [None] * (len(log) - 1)
    unset = Localiser(parse({"seed": 0, **DEMO_SETTINGS}))  # CEAMCL's own cap, 20,000
    unset.set_map(grid)
    unset.scan(tuple(log.odometry[0]), log.scan(0))
    assert cap_notice(unset.filter) is None
    poses = np.array([h.pose for h in localiser.filter.hypotheses()])
    for image in symmetric_images(log.true_poses[-1]):
        assert np.hypot(*(poses[:, :2] - image[:2]).T).min() < 0.1
