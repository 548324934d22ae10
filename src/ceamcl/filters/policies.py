"""When to update or resample: small policies that combine (Beluga's ``on_motion``,
``every_n``, ``|`` and ``&``).

A policy is a predicate over a :class:`Context`, the few facts a filter hands it: the
odometry motion since the last update, a count kept by the filter, the particle set. Policies
hold no state, so a filter's decisions stay in the filter and a run is reproducible::

    update_when = on_motion(0.25, 0.2)              # KLD-AMCL's update thresholds
    resample_when = every_n(2) & ess_below(0.5)      # a combination
    if update_when(Context(motion=odom - odom_at_update)): ...
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.particles import ParticleSet
from ceamcl.filters.resampling import effective_sample_size


@dataclass(frozen=True, eq=False)
class Context:
    """What a policy may look at.

    motion: odometry pose change ``(dx, dy, dtheta)`` since the last filter update (odometry
        frame, heading not wrapped).
    count: a count the filter keeps (e.g. filter updates since the initialisation, from 1).
    particles: the particle set.
    """

    motion: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    count: int = 0
    particles: ParticleSet | None = None


class Policy:
    """A yes/no decision over a :class:`Context`; ``a | b`` and ``a & b`` combine two."""

    def __call__(self, ctx: Context) -> bool:
        raise NotImplementedError

    def __or__(self, other: Policy) -> Policy:
        return AnyOf((self, other))

    def __and__(self, other: Policy) -> Policy:
        return AllOf((self, other))


@dataclass(frozen=True)
class AnyOf(Policy):
    """True when any of the policies is (evaluated in order, stopping at the first)."""

    policies: tuple[Policy, ...]

    def __call__(self, ctx: Context) -> bool:
        return any(p(ctx) for p in self.policies)


@dataclass(frozen=True)
class AllOf(Policy):
    """True when every policy is (evaluated in order, stopping at the first False)."""

    policies: tuple[Policy, ...]

    def __call__(self, ctx: Context) -> bool:
        return all(p(ctx) for p in self.policies)


@dataclass(frozen=True)
class OnMotion(Policy):
    """True once the odometry has moved more than ``min_distance_m`` along x or y, or turned
    more than ``min_angle_rad``, since the last update (amcl's ``update_min_d``,
    ``update_min_a``, tested per axis of the frame the context's motion is given in: the
    odometry frame where the runner or the ROS node gates, as amcl does; the robot's axes at
    the last initialisation inside KLD-AMCL, which sees only increments)."""

    min_distance_m: float
    min_angle_rad: float

    def __call__(self, ctx: Context) -> bool:
        d = ctx.motion
        da = math.remainder(float(d[2]), 2.0 * math.pi)
        return (
            abs(d[0]) > self.min_distance_m
            or abs(d[1]) > self.min_distance_m
            or abs(da) > self.min_angle_rad
        )


@dataclass(frozen=True)
class EveryN(Policy):
    """True at every ``n``-th count (amcl's ``resample_interval``)."""

    n: int

    def __call__(self, ctx: Context) -> bool:
        return ctx.count % self.n == 0


@dataclass(frozen=True)
class EssBelow(Policy):
    """True when the effective sample size ``1 / sum w_i^2`` falls below ``fraction * N``
    (Doucet et al. 2000; 1.0 resamples every step)."""

    fraction: float

    def __call__(self, ctx: Context) -> bool:
        if ctx.particles is None:
            raise ValueError("ess_below: the context holds no particle set")
        w = ctx.particles.weights
        return effective_sample_size(w) < self.fraction * w.size


def on_motion(min_distance_m: float, min_angle_rad: float) -> Policy:
    """:class:`OnMotion`."""
    return OnMotion(min_distance_m, min_angle_rad)


def every_n(n: int) -> Policy:
    """:class:`EveryN`."""
    if n < 1:
        raise ValueError(f"every_n: expected n >= 1, got {n}")
    return EveryN(n)


def ess_below(fraction: float) -> Policy:
    """:class:`EssBelow`."""
    return EssBelow(fraction)


__all__ = [
    "AllOf",
    "AnyOf",
    "Context",
    "EssBelow",
    "EveryN",
    "OnMotion",
    "Policy",
    "ess_below",
    "every_n",
    "on_motion",
]
