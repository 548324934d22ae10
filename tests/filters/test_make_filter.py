"""make_filter: names, configs and sample sizes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import ConfigError
from ceamcl.filters import (
    CEAMCL,
    GMCL,
    MCL,
    CEAMCLConfig,
    GMCLConfig,
    MCLConfig,
    make_filter,
)
from ceamcl.maps.worlds import get_world
from ceamcl.motion.odometry import DEFAULT_STRIDE_M, OdometryMotionModel, OdometryNoise


def test_a_config_reaches_its_filter() -> None:
    grid = get_world("small-office")
    f = make_filter("ceamcl", grid, np.random.default_rng(0), config=CEAMCLConfig(delta_per_m2=40))
    assert isinstance(f, CEAMCL) and f.config.delta_per_m2 == 40
    g = make_filter("gmcl", grid, np.random.default_rng(0), config=GMCLConfig(), n_particles=77)
    assert isinstance(g, GMCL) and g.config.n_particles == 77


def test_a_motion_model_reaches_its_filter_and_is_checked() -> None:
    """The default counts strides of travel; amcl's rule is one argument away."""
    grid = get_world("small-office")
    assert make_filter("mcl", grid, np.random.default_rng(0)).motion.stride_m == DEFAULT_STRIDE_M
    amcl_rule = OdometryMotionModel(OdometryNoise(0.1, 0.1, 0.1, 0.1), stride_m=None)
    for name in ("ceamcl", "mcl", "gmcl", "kld-amcl"):
        f = make_filter(name, grid, np.random.default_rng(0), motion=amcl_rule)
        assert f.motion is amcl_rule  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match="not both"):
        make_filter(
            "mcl", grid, np.random.default_rng(0), motion=amcl_rule, odometry_noise=OdometryNoise()
        )
    with pytest.raises(ConfigError, match="motion: expected an OdometryMotionModel, got dict"):
        make_filter("mcl", grid, np.random.default_rng(0), motion={})  # type: ignore[arg-type]


def test_a_config_of_another_filter_is_refused() -> None:
    grid = get_world("small-office")
    with pytest.raises(ConfigError, match="mcl takes a MCLConfig, got GMCLConfig"):
        make_filter("mcl", grid, np.random.default_rng(0), config=GMCLConfig())
    with pytest.raises(ConfigError, match="config: ceamcl"):
        make_filter("ceamcl", grid, np.random.default_rng(0), config=MCLConfig())
    assert type(make_filter("mcl", grid, np.random.default_rng(0))) is MCL


def test_an_unknown_sensor_model_is_refused_before_any_run(tmp_path: Path) -> None:
    """``--sensor`` in the library: a name outside ``SENSOR_MODELS`` is a ConfigError naming
    the field and the choices, from the registry and from the runs that take it (before any
    window is cut or file written)."""
    from ceamcl.experiments.evaluate_log import evaluate_log
    from ceamcl.filters.registry import SENSOR_MODELS, check_sensor

    grid = get_world("small-office")
    for call in (
        lambda: check_sensor("sonar"),
        lambda: make_filter("mcl", grid, np.random.default_rng(0), sensor="sonar"),
        lambda: evaluate_log(None, grid, ["mcl"], sensor="sonar", out=tmp_path),  # type: ignore[arg-type]
    ):
        with pytest.raises(ConfigError, match="sensor: unknown sensor model 'sonar'") as info:
            call()
        assert all(name in str(info.value) for name in SENSOR_MODELS)
    assert not any(tmp_path.iterdir())  # nothing written
    for name in SENSOR_MODELS:
        check_sensor(name)


def test_a_run_names_the_sensor_model_its_algorithm_weighs_with() -> None:
    """``ceamcl run`` and ``summary.json`` name the model the filter weighs with: the one
    asked for, but for the Nav2 wheel, which weighs with its own beam model whatever it is
    given (as the comparisons' reports say)."""
    from ceamcl.filters.registry import SENSOR_MODELS, describe_sensor, sensor_of

    for name in SENSOR_MODELS:
        assert sensor_of("ceamcl", name) == sensor_of("mcl-tuned", name) == name
        assert sensor_of("nav2-amcl", name) == "the wheel's own beam model"
        assert describe_sensor(name) == (
            f"{name} for every algorithm but nav2-amcl (the wheel's own beam model)"
        )


@pytest.mark.parametrize("count", [100.5, True, 0, -3, "100"])
def test_a_particle_count_must_be_a_positive_whole_number(count: object) -> None:
    """100.5 and True passed the check and failed later with a TypeError."""
    with pytest.raises(ConfigError, match="particles: expected a positive whole count"):
        make_filter("mcl", get_world("small-office"), np.random.default_rng(0), n_particles=count)  # type: ignore[arg-type]


def test_a_numpy_whole_count_is_a_count() -> None:
    f = make_filter(
        "mcl", get_world("small-office"), np.random.default_rng(0), n_particles=np.int64(300)
    )
    assert f.config.n_particles == 300  # type: ignore[attr-defined]


def test_ceamcl_hypotheses_are_checked_and_capped_by_max_samples() -> None:
    """initialise_hypotheses raised bare numpy errors for an empty list or a 2-vector, and
    300 poses gave 90,000 samples against a cap of 20,000."""
    from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig

    grid = get_world("small-office")
    cfg = CEAMCLConfig(max_samples=2_000)
    f = make_filter("ceamcl", grid, np.random.default_rng(1), config=cfg)
    assert isinstance(f, CEAMCL)
    cov = np.diag([0.01, 0.01, 0.01])
    for bad in ([], [1.0, 2.0], [[1.0, 2.0]]):
        with pytest.raises(ConfigError, match=r"poses: expected one or more poses .* \(K, 3\)"):
            f.initialise_hypotheses(bad, cov)
    free = grid.sample_free_poses(60, np.random.default_rng(2))
    f.initialise_hypotheses(free, cov)
    assert f.particles().poses.shape[0] <= cfg.max_samples
    assert len(f.hypotheses()) == 60
    with pytest.raises(ConfigError, match="exceed max_samples 2000"):
        f.initialise_hypotheses(grid.sample_free_poses(700, np.random.default_rng(3)), cov)
    assert len(f.hypotheses()) == 60  # a refusal leaves the filter as it was


@pytest.mark.parametrize("algorithm", ["mcl", "gmcl", "kld-amcl", "ceamcl", "mcl-tuned"])
def test_a_filter_used_before_its_initialisation_says_so(algorithm: str) -> None:
    """Before initialise_global / initialise_pose, MCL, GMCL and KLD-AMCL reported a certain
    pose at the map origin (zero covariance, one hypothesis of weight 1) and tracked from
    there; CEAMCL's first step quietly started a global localisation. Every call now raises
    one FilterStateError saying what to call first, and an initialisation ends it."""
    from ceamcl.errors import CeamclError, FilterStateError
    from ceamcl.motion.odometry import OdometryIncrement
    from ceamcl.sensors.scan import LaserScan

    grid = get_world("small-office")
    f = make_filter(algorithm, grid, np.random.default_rng(0), n_particles=200)
    scan = LaserScan(np.full(181, 2.0), -np.pi / 2, np.pi / 180, 0.02, 8.0)
    calls = {
        "step": lambda: f.step(OdometryIncrement(0.1, 0.0, 0.0), scan),
        "estimate": f.estimate,
        "hypotheses": f.hypotheses,
        "state": f.state,
        "particles": f.particles,
        "particle_weights": f.particle_weights,
    }
    for method, call in calls.items():
        with pytest.raises(FilterStateError, match=rf"{method}\(\) before the filter was") as info:
            call()
        assert "call initialise_global(scan) or initialise_pose(pose, covariance) first" in str(
            info.value
        )
        assert isinstance(info.value, CeamclError)
    free = grid.sample_free_poses(1, np.random.default_rng(1))[0]
    f.initialise_pose(free, np.diag([0.01, 0.01, 0.01]))
    for call in calls.values():
        call()


RNG_MESSAGE = (
    r"^rng: expected numpy.random.Generator, got {}; use numpy.random.default_rng\(seed\)$"
)


@pytest.mark.parametrize(
    ("rng", "got"), [(3, "int"), (None, "None"), (np.random.RandomState(0), "RandomState")]
)
def test_a_seed_where_a_generator_belongs_is_refused_at_once(rng: object, got: str) -> None:
    """A seed, None or a RandomState was accepted and failed at the first draw, deep inside
    ('int' object has no attribute 'integers'): refused, with the fix, by make_filter and by
    every filter's constructor."""
    from ceamcl.errors import InputTypeError
    from ceamcl.filters import KLDAMCL
    from ceamcl.motion.odometry import OdometryMotionModel
    from ceamcl.sensors import LikelihoodFieldModel

    grid = get_world("small-office")
    for algorithm in ("ceamcl", "mcl", "gmcl", "kld-amcl"):
        with pytest.raises(InputTypeError, match=RNG_MESSAGE.format(got)):
            make_filter(algorithm, grid, rng)  # type: ignore[arg-type]
    for cls in (CEAMCL, MCL, GMCL, KLDAMCL):
        with pytest.raises(TypeError, match=RNG_MESSAGE.format(got)):
            cls(grid, OdometryMotionModel(), LikelihoodFieldModel(grid), rng=rng)  # type: ignore[arg-type]


@pytest.mark.parametrize("algorithm", ["mcl", "gmcl", "kld-amcl", "ceamcl"])
def test_wrong_argument_types_are_named_before_the_filter_changes(algorithm: str) -> None:
    """An ndarray for a scan, a tuple for an increment or an occupancy array for a grid gave
    AttributeErrors from inside the library ('numpy.ndarray' object has no attribute
    'n_beams', 'tuple' object has no attribute 'rot1', ... no attribute 'derived')."""
    from ceamcl.errors import InputTypeError
    from ceamcl.motion.odometry import OdometryIncrement
    from ceamcl.sensors.scan import LaserScan

    grid = get_world("small-office")
    with pytest.raises(InputTypeError, match=r"^grid: expected OccupancyGrid, got ndarray; load"):
        make_filter(algorithm, np.zeros((10, 10)), np.random.default_rng(0))  # type: ignore[arg-type]
    f = make_filter(algorithm, grid, np.random.default_rng(0), n_particles=200)
    ranges = np.full(181, 2.0)
    for bad in (ranges, None):
        with pytest.raises(InputTypeError, match=r"^scan: expected LaserScan, got \w+; wrap"):
            f.initialise_global(bad)  # type: ignore[arg-type]
    scan = LaserScan(ranges, -np.pi / 2, np.pi / 180, 0.02, 8.0)
    f.initialise_global(scan)
    t = f.t  # type: ignore[attr-defined]
    for increment in ((0.1, 0.0, 0.0), np.array([0.1, 0.0, 0.0])):
        with pytest.raises(InputTypeError, match=r"^increment: expected OdometryIncrement, got"):
            f.step(increment, scan)  # type: ignore[arg-type]
    with pytest.raises(InputTypeError, match=r"^scan: expected LaserScan or None, got ndarray"):
        f.step(OdometryIncrement(0.1, 0.0, 0.0), ranges)  # type: ignore[arg-type]
    assert f.t == t  # type: ignore[attr-defined]  # refused before any change
    f.step(OdometryIncrement(0.1, 0.0, 0.0), None)


PROTOCOL_METHODS = (
    "initialise_global",
    "initialise_pose",
    "step",
    "estimate",
    "hypotheses",
    "state",
    "particles",
    "particle_weights",
)


def test_the_interface_and_every_filter_document_their_methods() -> None:
    """``help(f.step)`` said nothing: the protocol's methods had no docstrings, nor MCL's
    and GMCL's estimate, hypotheses, particles and particle_weights, CEAMCL's hypotheses
    and particles or KLD-AMCL's particle_weights."""
    import inspect

    from ceamcl.filters import KLDAMCL
    from ceamcl.filters.base import LocalisationFilter

    for method in PROTOCOL_METHODS:
        doc = inspect.getdoc(getattr(LocalisationFilter, method)) or ""
        assert "FilterStateError" in doc or method.startswith("initialise"), method
        assert len(doc) > 100, method
    for cls in (MCL, GMCL, KLDAMCL, CEAMCL):
        for method in PROTOCOL_METHODS:
            assert inspect.getdoc(getattr(cls, method)), f"{cls.__name__}.{method}"
