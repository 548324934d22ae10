"""The node's parameters, read without ROS: Nav2's names and defaults, checks, mapping."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from ceamcl.errors import ConfigError
from ceamcl.filters.ceamcl.config import CEAMCLConfig
from ceamcl.filters.kld_amcl import KLDAMCLConfig
from ceamcl.ros.params import NAV2_DEFAULTS, flatten, load_yaml, parse


def test_defaults_are_nav2s_and_ceamcl() -> None:
    p = parse({})
    assert p.algorithm == "ceamcl" and p.seed == 0
    assert isinstance(p.config, CEAMCLConfig)
    assert p["z_hit"] == 0.5 and p["update_min_d"] == 0.25
    assert p["base_frame_id"] == "base_footprint"
    assert p.sensor == "likelihood-field"
    assert p.warnings == ()


def test_every_problem_is_named_at_once() -> None:
    with pytest.raises(ConfigError) as err:
        parse(
            {
                "alhpa1": 0.1,
                "z_hit": 2.0,
                "max_beams": "sixty",
                "seed": -1,
                "laser_model_type": "likelihood_field_prob",
                "min_particles": 900,
                "max_particles": 100,
            }
        )
    text = str(err.value)
    for expected in (
        "unknown parameter: alhpa1",
        "z_hit: expected a number in [0, 1], got 2.0",
        "max_beams: expected an integer, got 'sixty'",
        "seed: expected a non-negative integer",
        "laser_model_type: expected one of",
        "max_particles: expected a count >= min_particles (900), got 100",
    ):
        assert expected in text


def test_nav2_particle_filter_settings_reach_kld_amcl() -> None:
    p = parse(
        {
            "algorithm": "kld-amcl",
            "pf_err": 0.02,
            "pf_z": 3.0,
            "min_particles": 100,
            "recovery_alpha_slow": 0.001,
            "recovery_alpha_fast": 0.1,
            "resample_interval": 2,
            "kld_amcl.bin_xy_m": 0.25,
        }
    )
    c = p.config
    assert isinstance(c, KLDAMCLConfig)
    assert (c.kld_err, c.kld_z, c.min_particles, c.alpha_slow, c.alpha_fast) == (
        0.02,
        3.0,
        100,
        0.001,
        0.1,
    )
    assert c.resample_interval == 2 and c.bin_xy_m == 0.25
    # the node gates updates itself (Nav2's update_min_d/a), the filter updates when asked
    assert c.update_min_d == 0.0 and c.update_min_a == 0.0


def test_settings_an_algorithm_lacks_are_warned_and_others_kept_aside() -> None:
    p = parse(
        {
            "recovery_alpha_fast": 0.1,
            "ceamcl.delta_per_m2": 40,
            "gmcl.cluster_cell_m": 0.3,
            "save_pose_rate": 1.0,
        }
    )
    assert p.config.delta_per_m2 == 40
    assert "recovery_alpha_fast: ceamcl has no such setting; ignored" in p.warnings
    assert "save_pose_rate: not implemented by this node; ignored" in p.warnings
    with pytest.raises(ConfigError, match=r"unknown parameter: ceamcl.no_such_field"):
        parse({"ceamcl.no_such_field": 1})
    with pytest.raises(ConfigError, match=r"ceamcl.delta_per_m2: expected a number"):
        parse({"ceamcl.delta_per_m2": "many"})


def test_nav2_beam_skipping_reaches_ceamcls_and_is_warned_elsewhere() -> None:
    """CEAMCL skips beams while one species tracks (on by default): Nav2's distance and, where
    set, error threshold set its test (unset, CEAMCL's own 1.0 stands, not Nav2's default 0.9:
    docs/ceamcl.md, departure 34), and do_beamskip adds amcl's vote at beam_skip_threshold."""
    default = parse({}).config.beam_skip
    assert (default.distance_m, default.error_threshold, default.threshold) == (0.5, 1.0, None)
    assert parse({"beam_skip_error_threshold": 0.9}).config.beam_skip.error_threshold == 0.9
    p = parse(
        {
            "do_beamskip": True,
            "beam_skip_distance": 0.3,
            "beam_skip_threshold": 0.4,
            "beam_skip_error_threshold": 0.8,
        }
    )
    skip = p.config.beam_skip
    assert (skip.distance_m, skip.error_threshold, skip.threshold) == (0.3, 0.8, 0.4)
    assert p.warnings == ()
    off = parse({"beam_skip_distance": 0.3, "beam_skip_threshold": 0.4}).config.beam_skip
    assert (off.distance_m, off.threshold) == (0.3, None)  # no vote without do_beamskip
    mcl = parse({"algorithm": "kld-amcl", "do_beamskip": True})
    assert "do_beamskip: kld-amcl skips no beams; ignored" in mcl.warnings
    with pytest.raises(ConfigError) as err:
        parse({"beam_skip_distance": 0.0, "beam_skip_threshold": 1.5})
    assert "beam_skip_distance: expected a positive distance in metres, got 0.0" in str(err.value)
    assert "beam_skip_threshold: expected a share in (0, 1], got 1.5" in str(err.value)


def test_yaml_file_sections_and_nesting(tmp_path: Path) -> None:
    f = tmp_path / "nav2_params.yaml"
    f.write_text(
        "/**:\n  ros__parameters:\n    use_sim_time: true\n"
        "amcl:\n  ros__parameters:\n    alpha1: 0.3\n    initial_pose:\n      x: 1.5\n"
        "    ceamcl:\n      delta_per_m2: 20.0\n"
        "bt_navigator:\n  ros__parameters:\n    whatever: 1\n"
    )
    values = load_yaml(f)
    assert values == {
        "use_sim_time": True,
        "alpha1": 0.3,
        "initial_pose.x": 1.5,
        "ceamcl.delta_per_m2": 20.0,
    }
    p = parse(values)
    assert p["initial_pose.x"] == 1.5 and p.config.delta_per_m2 == 20.0
    assert flatten({"a": {"b": {"c": 1}}}) == {"a.b.c": 1}
    assert set(NAV2_DEFAULTS) >= {"alpha5", "laser_max_range", "transform_tolerance"}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("amcl: [1, 2]\n", "expected a mapping with ros__parameters"),
        ("- 1\n", "expected a mapping"),
        ("a: [\n", "not a YAML file"),
    ],
)
def test_bad_yaml_files_are_named(tmp_path: Path, text: str, match: str) -> None:
    f = tmp_path / "p.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError, match=match) as err:
        load_yaml(f)
    assert str(f) in str(err.value)


def test_the_example_parameter_file_is_valid() -> None:
    example = Path(__file__).resolve().parents[2] / "ros" / "ceamcl_params.yaml"
    p = parse(load_yaml(example))
    assert p.algorithm == "ceamcl" and p["z_hit"] == 0.95 and p.warnings == ()


def _built(values: dict[str, object]):  # type: ignore[no-untyped-def]
    from ceamcl.maps.worlds import get_world
    from ceamcl.ros.localiser import Localiser

    localiser = Localiser(parse(values))
    localiser.set_map(get_world("small-office"))
    return localiser.filter


def test_what_the_parameters_set_wins_over_a_presets_tuning() -> None:
    """A preset's tuned laser settings and particle count stand where the parameters leave
    them at Nav2's defaults; where the parameters set them, the user's values win (they were
    overwritten by the preset's, without a word)."""
    from ceamcl.filters.registry import get

    preset = get("mcl-tuned")
    tuned = _built({"algorithm": "mcl-tuned"})
    assert (tuned.sensor.config.max_beams, tuned.sensor.config.temper) == (
        preset.sensor_settings["max_beams"],
        preset.sensor_settings["temper"],
    )
    assert tuned.config.n_particles == preset.default_config().n_particles == 5000
    chosen = _built({"algorithm": "mcl-tuned", "max_beams": 90, "laser_temper": 0.5})
    assert (chosen.sensor.config.max_beams, chosen.sensor.config.temper) == (90, 0.5)
    assert _built({"algorithm": "mcl-tuned", "max_particles": 1500}).config.n_particles == 1500
    # an algorithm's own count, set in its namespace, is not replaced by max_particles
    assert _built({"algorithm": "mcl", "mcl.n_particles": 3000}).config.n_particles == 3000
    kld = _built({"algorithm": "kld-amcl", "kld_amcl.max_particles": 4000})
    assert kld.config.max_particles == 4000
    assert _built({"algorithm": "mcl"}).config.n_particles == NAV2_DEFAULTS["max_particles"]


def test_max_particles_set_is_ceamcls_cap() -> None:
    """CEAMCL takes no particle count (eq. 5 sizes its species). ``max_particles``, where the
    parameters set it, caps its total (``max_samples``) and its ``initialise_pose`` species;
    left at Nav2's default CEAMCL keeps its own cap; ``ceamcl.max_samples`` wins; a cap below
    a species' least size is refused, naming the parameter."""
    capped = _built({"max_particles": 150, "min_particles": 100}).config
    assert (capped.max_samples, capped.tracking_samples) == (150, 150)
    assert _built({"max_particles": 2000}).config.max_samples == 2000
    own = CEAMCLConfig()
    default = _built({}).config
    assert (default.max_samples, default.tracking_samples) == (
        own.max_samples,
        own.tracking_samples,
    )
    chosen = _built({"max_particles": 150, "min_particles": 100, "ceamcl.max_samples": 9000})
    assert chosen.config.max_samples == 9000
    with pytest.raises(ConfigError, match="max_particles: CEAMCL's species hold at least 3"):
        parse({"max_particles": 2, "min_particles": 1})


def test_the_nav2_peer_takes_nav2s_laser_settings() -> None:
    from ceamcl.peers import available

    if not available():
        pytest.skip("Nav2 AMCL wheel not installed (pip install 'ceamcl[peers]')")
    values = {"algorithm": "nav2-amcl", "max_beams": 30, "sigma_hit": 0.1, "z_hit": 0.9}
    beam = parse(values).config.beam
    assert (beam.max_beams, beam.sigma_hit_m, beam.z_hit) == (30, 0.1, 0.9)
    warned = parse({**values, "laser_temper": 0.5}).warnings
    assert any(w.startswith("laser_temper: nav2-amcl weighs with") for w in warned)


def test_nav2_defaults_do_not_undo_what_a_preset_or_recovery_is_for() -> None:
    """kld-amcl-recovery in the node ran with recovery off: Nav2's default recovery rates
    (0.0) replaced its own, and the presets' KLD quantile became Nav2's pf_z. Nav2's defaults
    still reach plain kld-amcl (the drop-in), and what the parameters set reaches every one."""
    from ceamcl.filters import registry

    recovery = parse({"algorithm": "kld-amcl-recovery"}).config
    # its own settings but the update thresholds, which the node's motion gate applies
    gated = dataclasses.replace(registry.get("kld-amcl-recovery").default(), update_min_d=0.0)
    assert recovery == dataclasses.replace(gated, update_min_a=0.0)
    assert recovery.recovery and 0 < recovery.alpha_slow < recovery.alpha_fast
    for name in ("kld-amcl-recovery", "kld-amcl-tuned"):
        assert parse({"algorithm": name}).config.kld_z == registry.get(name).default().kld_z
    set_ = parse({"algorithm": "kld-amcl-recovery", "recovery_alpha_slow": 0.002, "pf_z": 0.5})
    assert (set_.config.alpha_slow, set_.config.kld_z) == (0.002, 0.5)
    plain = parse({"algorithm": "kld-amcl"}).config
    assert (plain.alpha_slow, plain.kld_z) == (0.0, NAV2_DEFAULTS["pf_z"])


@pytest.mark.parametrize(
    ("values", "says"),
    [
        ({"z_hit": 0.0}, "likelihood-field model: z_hit must be > 0"),
        ({"laser_likelihood_max_dist": 0.0}, "laser_likelihood_max_dist: expected > 0"),
        ({"laser_model_type": "beam", "lambda_short": 0.0}, "beam model: lambda_short"),
        ({"laser_min_range": 5.0, "laser_max_range": 2.0}, "expected min < max"),
        ({"algorithm": "nav2-amcl", "z_hit": 0.0}, "beam model: z_hit must be > 0"),
    ],
)
def test_laser_settings_the_model_refuses_fail_configure(
    values: dict[str, object], says: str
) -> None:
    """They passed configure and failed when the map came: an active node that logged a
    traceback and never localised."""
    with pytest.raises(ConfigError, match=says):
        parse(values)
