"""The node's parameters: Nav2 AMCL's names and defaults, plus ``algorithm``, ``seed`` and each
algorithm's own config fields, read and checked without ROS.

Nav2 reads its parameters from a YAML file (``amcl: ros__parameters: {...}``); the node reads the
same file, and every value a ROS launch passes arrives here as a flat ``{dotted.name: value}``
map. :func:`parse` checks every name and value and returns :class:`NodeParams`, or raises a
:class:`ceamcl.errors.ConfigError` naming every unknown parameter and every bad value at once.

Algorithm config fields are set as ``<algorithm>.<field>`` with dashes as underscores, e.g.
``ceamcl.delta_per_m2: 40.0`` or ``kld_amcl_recovery.kld_err: 0.02`` (scalar fields only).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ceamcl.errors import ConfigError
from ceamcl.filters import registry
from ceamcl.io.safe_yaml import yaml_problem
from ceamcl.sensors.beam_model import BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig

#: Nav2 AMCL's parameters and defaults (nav2_amcl, Jazzy/Kilted), by name.
NAV2_DEFAULTS: dict[str, Any] = {
    "alpha1": 0.2,
    "alpha2": 0.2,
    "alpha3": 0.2,
    "alpha4": 0.2,
    "alpha5": 0.2,
    "always_reset_initial_pose": False,
    "base_frame_id": "base_footprint",
    "beam_skip_distance": 0.5,
    "beam_skip_error_threshold": 0.9,
    "beam_skip_threshold": 0.3,
    "do_beamskip": False,
    "first_map_only": False,
    "global_frame_id": "map",
    "lambda_short": 0.1,
    "laser_likelihood_max_dist": 2.0,
    "laser_max_range": 100.0,
    "laser_min_range": -1.0,
    "laser_model_type": "likelihood_field",
    "map_topic": "map",
    "max_beams": 60,
    "max_particles": 2000,
    "min_particles": 500,
    "odom_frame_id": "odom",
    "pf_err": 0.05,
    "pf_z": 0.99,
    "recovery_alpha_fast": 0.0,
    "recovery_alpha_slow": 0.0,
    "resample_interval": 1,
    "robot_model_type": "nav2_amcl::DifferentialMotionModel",
    "save_pose_rate": 0.5,
    "scan_topic": "scan",
    "set_initial_pose": False,
    "initial_pose.x": 0.0,
    "initial_pose.y": 0.0,
    "initial_pose.z": 0.0,
    "initial_pose.yaw": 0.0,
    "sigma_hit": 0.2,
    "tf_broadcast": True,
    "transform_tolerance": 1.0,
    "update_min_a": 0.2,
    "update_min_d": 0.25,
    "z_hit": 0.5,
    "z_max": 0.05,
    "z_rand": 0.5,
    "z_short": 0.05,
}
#: The node's own parameters (not Nav2's).
#: (``laser_temper`` too, when given: unset, each laser model keeps its own default.)
OWN_DEFAULTS: dict[str, Any] = {"algorithm": "ceamcl", "seed": 0}
#: Parameters every ROS node or Nav2 lifecycle node may be given; accepted and not used here.
IGNORED = frozenset(
    {
        "use_sim_time",
        "bond_heartbeat_period",
        "bond_disable_heartbeat_timeout",
        "introspection_mode",
        "start_type_description_service",
        "qos_overrides",
    }
)
LASER_MODELS = {"likelihood_field": "likelihood-field", "beam": "beam"}
DIFFERENTIAL = ("nav2_amcl::DifferentialMotionModel", "differential")
#: Nav2 parameters this node reads but does not (yet) act on: a warning is logged when set.
NOT_IMPLEMENTED = ("save_pose_rate", "always_reset_initial_pose")
#: Nav2's beam-skipping parameters, for an algorithm that skips beams (``beam_skip`` in its
#: config: CEAMCL, docs/ros.md).
BEAM_SKIP = (
    "do_beamskip",
    "beam_skip_distance",
    "beam_skip_threshold",
    "beam_skip_error_threshold",
)


@dataclass(frozen=True)
class NodeParams:
    """Every parameter, checked: Nav2's by their Nav2 names, the algorithm's config built."""

    nav2: dict[str, Any]
    algorithm: str
    seed: int
    config: Any
    warnings: tuple[str, ...] = ()
    algorithm_overrides: dict[str, Any] = field(default_factory=dict)
    #: the laser model's tempering (``temper`` of the sensor configs, docs/sensor-models.md);
    #: ``None``: the model's own default (0.2 for the product, none for amcl's scoring)
    laser_temper: float | None = None
    #: the names the parameters set (the rest took their defaults): what the user chose wins
    #: over a preset's tuned settings (docs/ros.md)
    given: frozenset[str] = frozenset()

    def __getitem__(self, name: str) -> Any:
        return self.nav2[name]

    @property
    def sensor(self) -> str:
        return LASER_MODELS[self.nav2["laser_model_type"]]


def prefix(algorithm: str) -> str:
    """The parameter namespace of an algorithm's own config fields."""
    return algorithm.replace("-", "_")


def flatten(tree: Mapping[str, Any], parent: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``, as ROS names nested YAML parameters."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{parent}.{key}" if parent else str(key)
        if isinstance(value, Mapping):
            out.update(flatten(value, name))
        else:
            out[name] = value
    return out


def load_yaml(path: str | Path, node_name: str = "amcl") -> dict[str, Any]:
    """The flat parameters for ``node_name`` in a ROS 2 parameter file (``/**`` entries too).

    The file's other nodes (a full ``nav2_params.yaml``) are left alone.
    """
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the parameter file ({exc.strerror})") from None
    except yaml.YAMLError as exc:  # one line: where, and what the parser found
        line, problem = yaml_problem(exc)
        at = "" if line is None else f" (line {line})"
        raise ConfigError(f"{p}: not a YAML file{at}: {problem}") from None
    if not isinstance(doc, Mapping):
        raise ConfigError(f"{p}: expected a mapping of node names to ros__parameters")
    out: dict[str, Any] = {}
    for key in ("/**", node_name, f"/{node_name}"):
        section = doc.get(key)
        if section is None:
            continue
        if not isinstance(section, Mapping) or not isinstance(
            section.get("ros__parameters", {}), Mapping
        ):
            raise ConfigError(f"{p}: {key}: expected a mapping with ros__parameters")
        out.update(flatten(section.get("ros__parameters") or {}))
    return out


def _check_type(name: str, value: Any, default: Any) -> str | None:
    if isinstance(default, bool):
        return None if isinstance(value, bool) else f"{name}: expected true or false, got {value!r}"
    if isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
        return None if ok else f"{name}: expected an integer, got {value!r}"
    if isinstance(default, float):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if ok and not math.isfinite(value):
            return f"{name}: expected a finite number, got {value!r}"
        return None if ok else f"{name}: expected a number, got {value!r}"
    if isinstance(default, str):
        ok = isinstance(value, str) and value != ""
        return None if ok else f"{name}: expected a non-empty string, got {value!r}"
    return None


def _check_ranges(p: dict[str, Any]) -> list[str]:
    errors: list[str] = []

    def need(ok: bool, name: str, what: str) -> None:
        if not ok:
            errors.append(f"{name}: expected {what}, got {p[name]!r}")

    for name in (
        "alpha1",
        "alpha2",
        "alpha3",
        "alpha4",
        "alpha5",
        "update_min_d",
        "update_min_a",
        "transform_tolerance",
        "laser_likelihood_max_dist",
        "recovery_alpha_fast",
        "recovery_alpha_slow",
        "lambda_short",
    ):
        need(p[name] >= 0, name, "a non-negative number")
    for name in ("z_hit", "z_rand", "z_short", "z_max", "pf_err"):
        need(0 <= p[name] <= 1, name, "a number in [0, 1]")
    need(p["pf_z"] > 0, "pf_z", "a positive number (the normal quantile z)")
    need(p["beam_skip_distance"] > 0, "beam_skip_distance", "a positive distance in metres")
    for name in ("beam_skip_threshold", "beam_skip_error_threshold"):
        need(0 < p[name] <= 1, name, "a share in (0, 1]")
    need(p["sigma_hit"] > 0, "sigma_hit", "a positive number")
    need(p["max_beams"] >= 2, "max_beams", "at least 2")
    need(p["resample_interval"] >= 1, "resample_interval", "at least 1")
    need(p["min_particles"] >= 1, "min_particles", "a positive count")
    need(
        p["max_particles"] >= max(1, p["min_particles"]),
        "max_particles",
        f"a count >= min_particles ({p['min_particles']})",
    )
    need(
        p["laser_model_type"] in LASER_MODELS,
        "laser_model_type",
        f"one of {', '.join(LASER_MODELS)}",
    )
    need(
        p["robot_model_type"] in DIFFERENTIAL,
        "robot_model_type",
        "nav2_amcl::DifferentialMotionModel (the omni model is not implemented)",
    )
    for name in ("global_frame_id", "odom_frame_id", "base_frame_id"):
        need("/" not in p[name].strip("/") and " " not in p[name], name, "a TF frame id")
    return errors


def laser_config(
    p: Mapping[str, Any], sensor: str, laser_temper: float | None
) -> BeamModelConfig | LikelihoodFieldConfig:
    """The laser model's config Nav2's parameters ask for (``sensor``: "beam" or
    "likelihood-field"); the config checks its values (ValueError)."""
    if sensor == "beam":
        return BeamModelConfig(**beam_settings(p), temper=laser_temper)
    return LikelihoodFieldConfig(
        z_hit=p["z_hit"],
        z_rand=p["z_rand"],
        sigma_hit_m=p["sigma_hit"],
        max_occ_dist_m=p["laser_likelihood_max_dist"],
        max_beams=p["max_beams"],
        temper=laser_temper,
    )


#: The laser configs' field names, as Nav2 names the parameters (for error messages).
_NAV2_NAMES = {"sigma_hit_m": "sigma_hit", "max_occ_dist_m": "laser_likelihood_max_dist"}


def _check_laser(p: Mapping[str, Any], sensor: str, laser_temper: float | None) -> list[str]:
    """What the laser model would refuse once a map arrives, said at configure: a node that
    configured and then failed on its map stayed active and never localised."""
    errors = []
    lo, hi = p["laser_min_range"], p["laser_max_range"]
    if lo > 0 and hi > 0 and not lo < hi:
        errors.append(
            f"laser_min_range/laser_max_range: expected min < max where both are set, got "
            f"{lo:g} and {hi:g}"
        )
    try:
        laser_config(p, sensor, laser_temper)
    except ValueError as exc:
        text = str(exc)
        for ours, nav2 in _NAV2_NAMES.items():
            text = text.replace(ours, nav2)
        errors.append(f"{sensor} model: {text}")
    return errors


def beam_settings(p: Mapping[str, Any]) -> dict[str, Any]:
    """Nav2's beam-model parameters as :class:`BeamModelConfig` fields (our model's, and the
    Nav2 peer's own)."""
    return {
        "z_hit": p["z_hit"],
        "z_short": p["z_short"],
        "z_max": p["z_max"],
        "z_rand": p["z_rand"],
        "sigma_hit_m": p["sigma_hit"],
        "lambda_short": p["lambda_short"],
        "max_beams": p["max_beams"],
    }


#: Algorithms whose own settings are tuned (the presets) or are what they are for
#: (``kld-amcl-recovery``'s recovery rates): Nav2's *defaults* do not replace them, only the
#: parameters the user sets (Nav2's 0.0 recovery rates turned kld-amcl-recovery's recovery off).
KEEPS_OWN_SETTINGS: frozenset[str] = frozenset({*registry.PRESETS, "kld-amcl-recovery"})


def _nav2_to_config(
    algorithm: str, p: dict[str, Any], config: Any, given: frozenset[str] = frozenset()
) -> tuple[Any, list[str]]:
    """Nav2's particle-filter parameters carried into the algorithm's config where it has the
    same knob (for :data:`KEEPS_OWN_SETTINGS`, only those in ``given``); a warning for each
    one set away from its default that this algorithm ignores."""
    names = {f.name for f in dataclasses.fields(config)}
    mapping = {
        "min_particles": ("min_particles", p["min_particles"]),
        "resample_interval": ("resample_interval", p["resample_interval"]),
        "recovery_alpha_slow": ("alpha_slow", p["recovery_alpha_slow"]),
        "recovery_alpha_fast": ("alpha_fast", p["recovery_alpha_fast"]),
        "pf_err": ("kld_err", p["pf_err"]),
        # Nav2 uses pf_z as the normal quantile z itself (pf_resample_limit), so do we.
        "pf_z": ("kld_z", p["pf_z"]),
        "update_min_d": ("update_min_d", 0.0),  # the node gates updates (localiser.MotionGate)
        "update_min_a": ("update_min_a", 0.0),
    }
    changes: dict[str, Any] = {}
    warnings: list[str] = []
    keeps_own = algorithm in KEEPS_OWN_SETTINGS
    for nav2_name, (field_name, value) in mapping.items():
        if field_name in names:
            if keeps_own and nav2_name not in given and not nav2_name.startswith("update_"):
                continue
            changes[field_name] = value
        elif p[nav2_name] != NAV2_DEFAULTS[nav2_name] and not nav2_name.startswith("update_"):
            warnings.append(f"{nav2_name}: {algorithm} has no such setting; ignored")
    if "max_samples" in names and "max_particles" in given:
        # CEAMCL sizes its species itself (eq. 5) and takes no particle count: a budget the
        # parameters set caps its total, as it caps Nav2's filter, and an initial pose's
        # species; unset, CEAMCL keeps its own cap (docs/ros.md). Its own ``ceamcl.*`` win.
        cap = p["max_particles"]
        if cap < config.min_species_size:
            raise ConfigError(
                f"max_particles: CEAMCL's species hold at least {config.min_species_size} "
                f"samples; expected >= {config.min_species_size}, got {cap}"
            )
        changes["max_samples"] = cap
        changes["tracking_samples"] = min(config.tracking_samples, cap)
    beam = getattr(config, "beam", None) if "beam" in names else None
    if isinstance(beam, BeamModelConfig):
        # an algorithm with a beam model of its own (the Nav2 peer): Nav2's laser settings
        changes["beam"] = dataclasses.replace(beam, **beam_settings(p))
        if p["laser_likelihood_max_dist"] != NAV2_DEFAULTS["laser_likelihood_max_dist"]:
            warnings.append(
                f"laser_likelihood_max_dist: {algorithm} has no likelihood field; ignored"
            )
    skip = getattr(config, "beam_skip", None) if "beam_skip" in names else None
    if skip is not None:
        # CEAMCL's own beam skipping (on while one species tracks) takes Nav2's distance, and
        # its error threshold where the parameters set it (Nav2's 0.9 is not CEAMCL's default:
        # departure 34); do_beamskip adds amcl's vote (docs/ros.md)
        changes["beam_skip"] = dataclasses.replace(
            skip,
            distance_m=p["beam_skip_distance"],
            error_threshold=(
                p["beam_skip_error_threshold"]
                if "beam_skip_error_threshold" in given
                else skip.error_threshold
            ),
            threshold=p["beam_skip_threshold"] if p["do_beamskip"] else None,
        )
    else:
        for name in BEAM_SKIP:
            if p[name] != NAV2_DEFAULTS[name]:
                why = "skips no beams" if "beam_skip" not in names else "has beam skipping off"
                warnings.append(f"{name}: {algorithm} {why}; ignored")
    return dataclasses.replace(config, **changes), warnings


def parse(values: Mapping[str, Any], given: Iterable[str] | None = None) -> NodeParams:
    """Check ``values`` (flat ROS parameter names) against the node's parameters. ``given``:
    the names the user set (default: every name in ``values``); the node passes its
    overrides, since it declares every other parameter with Nav2's default, and those
    defaults must not count as set (they would replace a preset's tuning).

    Raises :class:`ConfigError` listing every unknown name and bad value (none is applied).
    """
    chosen = frozenset(values if given is None else given)
    errors: list[str] = []
    algorithm = values.get("algorithm", OWN_DEFAULTS["algorithm"])
    if algorithm not in registry.names():
        errors.append(
            f"algorithm: unknown algorithm {algorithm!r}; expected one of "
            f"{', '.join(registry.names())}"
        )
        algorithm = OWN_DEFAULTS["algorithm"]
    else:
        reason = registry.unavailable_reason(algorithm)
        if reason is not None:
            errors.append(f"algorithm: {algorithm} cannot run here: {reason}")
    spec = registry.get(algorithm)
    default_config = spec.default()
    config_fields = {
        f.name: getattr(default_config, f.name)
        for f in dataclasses.fields(default_config)
        if isinstance(getattr(default_config, f.name), bool | int | float | str)
    }
    own = prefix(algorithm)
    all_prefixes = {prefix(n) for n in registry.names()}

    nav2 = dict(NAV2_DEFAULTS)
    overrides: dict[str, Any] = {}
    seed = OWN_DEFAULTS["seed"]
    laser_temper: float | None = None
    unknown: list[str] = []
    for name, value in values.items():
        head, _, tail = name.partition(".")
        if name in IGNORED or name.startswith("qos_overrides."):
            continue
        if name == "algorithm":
            continue
        if name == "seed":
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
            if not ok:
                errors.append(f"seed: expected a non-negative integer, got {value!r}")
            else:
                seed = value
        elif name == "laser_temper" and value is None:
            continue  # unset: the laser model's own default
        elif name == "laser_temper":
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if not (number and math.isfinite(value) and 0 < value <= 1):
                errors.append(f"laser_temper: expected a number in (0, 1], got {value!r}")
            else:
                laser_temper = float(value)
        elif name in NAV2_DEFAULTS:
            problem = _check_type(name, value, NAV2_DEFAULTS[name])
            if problem:
                errors.append(problem)
            else:
                nav2[name] = float(value) if isinstance(NAV2_DEFAULTS[name], float) else value
        elif head == own and tail in config_fields:
            problem = _check_type(name, value, config_fields[tail])
            if problem:
                errors.append(problem)
            else:
                overrides[tail] = value
        elif head in all_prefixes and tail:
            if head != own:
                continue  # another algorithm's settings, kept in a shared file
            unknown.append(name)
        else:
            unknown.append(name)
    if unknown:
        errors.insert(
            0,
            f"unknown parameter{'s' if len(unknown) > 1 else ''}: {', '.join(sorted(unknown))} "
            f"(Nav2 AMCL's names, algorithm, seed, laser_temper or {own}.<field of "
            f"{spec.config_type.__name__}>)",
        )
    errors.extend(_check_ranges(nav2))
    if not errors:  # the Nav2 peer weighs with the wheel's beam model, on Nav2's beam settings
        model = (
            "beam" if algorithm in registry.OWN_SENSOR else LASER_MODELS[nav2["laser_model_type"]]
        )
        errors.extend(_check_laser(nav2, model, laser_temper))
    if errors:
        raise ConfigError("; ".join(errors))

    config, warnings = _nav2_to_config(algorithm, nav2, default_config, chosen)
    try:
        config = dataclasses.replace(config, **overrides)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{own}: {exc}") from None
    if laser_temper not in (None, 1.0) and getattr(config, "scoring", None) == "ros":
        raise ConfigError(
            f"laser_temper: {algorithm} scores scans as amcl does (a sum of cubed beam "
            f"probabilities), which takes no tempering; got {laser_temper}"
        )
    for name in NOT_IMPLEMENTED:
        if nav2[name] != NAV2_DEFAULTS[name]:
            warnings.append(f"{name}: not implemented by this node; ignored")
    if laser_temper is not None and algorithm in registry.OWN_SENSOR:
        warnings.append(
            f"laser_temper: {algorithm} weighs with {registry.OWN_SENSOR[algorithm]}; ignored"
        )
    return NodeParams(
        nav2,
        algorithm,
        seed,
        config,
        tuple(warnings),
        overrides,
        laser_temper=laser_temper,
        given=chosen,
    )
