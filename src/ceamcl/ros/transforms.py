"""Planar transforms and a small TF buffer, without ROS.

``tf2_ros`` is not on PyPI, so the node keeps its own buffer of the few frames it needs
(``odom -> base`` over time, ``base -> laser`` usually static), fed from ``/tf`` and
``/tf_static``. Poses are ``(x, y, yaw)``; composition follows ``a_T_c = a_T_b * b_T_c``.
Dynamic transforms are interpolated between the two samples around the asked time (x, y
linearly, yaw along the shorter arc), as tf2 does; a time outside the samples held is an
:class:`ExtrapolationError` (tf2 refuses to extrapolate too).
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

Pose2 = tuple[float, float, float]

#: Samples kept per dynamic edge, and how far back (s): bounded whatever the sender sends.
MAX_SAMPLES = 2_000
CACHE_S = 10.0
#: Frames kept at most (a TF tree of a robot has tens).
MAX_FRAMES = 500


class TransformError(Exception):
    """A transform the buffer cannot give."""


class ExtrapolationError(TransformError):
    """The time asked is outside the samples held."""


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def compose(a: Pose2, b: Pose2) -> Pose2:
    """``a * b``: pose ``b`` given in frame ``a``, expressed in ``a``'s parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2]))


def inverse(a: Pose2) -> Pose2:
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), s * a[0] - c * a[1], wrap(-a[2]))


def yaw_of(x: float, y: float, z: float, w: float) -> float:
    """Yaw of a quaternion (rotation about z)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def is_upside_down(x: float, y: float, z: float, w: float) -> bool:
    """Whether the quaternion turns the z axis downwards (a laser mounted upside down)."""
    return 1.0 - 2.0 * (x * x + y * y) < 0.0


def quaternion_of(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def _interpolate(t0: float, p0: Pose2, t1: float, p1: Pose2, t: float) -> Pose2:
    if t1 <= t0:
        return p1
    r = (t - t0) / (t1 - t0)
    return (
        p0[0] + r * (p1[0] - p0[0]),
        p0[1] + r * (p1[1] - p0[1]),
        wrap(p0[2] + r * wrap(p1[2] - p0[2])),
    )


@dataclass
class _Edge:
    parent: str
    static: Pose2 | None = None
    times: list[float] = field(default_factory=list)
    poses: deque[Pose2] = field(default_factory=deque)

    def add(self, t: float, pose: Pose2) -> None:
        if self.times and t < self.times[-1]:
            # out of order (a replay restarted): start over from this sample, as tf2 does
            # after a jump back in time
            if t < self.times[-1] - CACHE_S or t < self.times[0]:
                self.times.clear()
                self.poses.clear()
            else:
                return
        if self.times and t == self.times[-1]:
            self.poses[-1] = pose
            return
        self.times.append(t)
        self.poses.append(pose)
        while len(self.times) > MAX_SAMPLES or self.times[-1] - self.times[0] > CACHE_S:
            self.times.pop(0)
            self.poses.popleft()

    def at(self, t: float | None) -> Pose2:
        if self.static is not None:
            return self.static
        if not self.times:
            raise TransformError("no sample")
        if t is None:
            return self.poses[-1]
        if t < self.times[0] or t > self.times[-1]:
            raise ExtrapolationError(
                f"time {t:.3f} is outside the samples held ({self.times[0]:.3f} to "
                f"{self.times[-1]:.3f})"
            )
        i = bisect.bisect_left(self.times, t)
        if self.times[i] == t:
            return self.poses[i]
        return _interpolate(self.times[i - 1], self.poses[i - 1], self.times[i], self.poses[i], t)


class TransformBuffer:
    """Planar TF tree: each child frame has one parent edge, static or sampled over time."""

    def __init__(self) -> None:
        self._edges: dict[str, _Edge] = {}

    def clear(self) -> None:
        self._edges.clear()

    def set_transform(
        self, parent: str, child: str, pose: Pose2, stamp: float, *, static: bool
    ) -> None:
        """Record ``parent -> child`` (the child's pose in the parent frame) at ``stamp``."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if not parent or not child or parent == child:
            raise TransformError(f"bad frame ids {parent!r} -> {child!r}")
        if not all(math.isfinite(v) for v in (*pose, stamp)):
            raise TransformError(f"{parent} -> {child}: non-finite transform or stamp")
        edge = self._edges.get(child)
        if edge is None or edge.parent != parent:
            if edge is None and len(self._edges) >= MAX_FRAMES:
                raise TransformError(f"more than {MAX_FRAMES} frames; {child!r} dropped")
            edge = _Edge(parent)
            self._edges[child] = edge
        if static:
            edge.static = pose
        else:
            edge.static = None
            edge.add(stamp, pose)

    def _ancestors(self, frame: str) -> list[str]:
        """``frame``, its parent, ... up to the root of its tree (no times involved)."""
        chain = [frame]
        while chain[-1] in self._edges and len(chain) <= MAX_FRAMES:
            chain.append(self._edges[chain[-1]].parent)
        return chain

    def _up_to(self, chain: list[str], top: str, t: float | None) -> Pose2:
        """``top_T_chain[0]``, composing the edges below ``top`` only (those above it, such
        as a post-dated ``map -> odom``, are not asked for a time they may not cover)."""
        pose: Pose2 = (0.0, 0.0, 0.0)
        for frame in chain[: chain.index(top)]:
            pose = compose(self._edges[frame].at(t), pose)
        return pose

    def lookup(self, target: str, source: str, t: float | None = None) -> Pose2:
        """``target_T_source`` at time ``t`` (``None``: the latest samples)."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return (0.0, 0.0, 0.0)
        chain_s, chain_t = self._ancestors(source), self._ancestors(target)
        common = next((f for f in chain_s if f in set(chain_t)), None)
        if common is None:
            raise TransformError(
                f"no transform from {target!r} to {source!r}: they are not connected "
                f"(known frames: {', '.join(sorted(self.frames())) or 'none'})"
            )
        try:
            top_T_s = self._up_to(chain_s, common, t)
            top_T_t = self._up_to(chain_t, common, t)
        except ExtrapolationError as exc:
            raise ExtrapolationError(f"{target} -> {source}: {exc}") from None
        except TransformError as exc:
            raise TransformError(f"{target} -> {source}: {exc}") from None
        return compose(inverse(top_T_t), top_T_s)

    def latest_stamp(self) -> float:
        """The newest time any sampled edge reaches (``-inf`` without samples)."""
        return max((e.times[-1] for e in self._edges.values() if e.times), default=-math.inf)

    def frames(self) -> set[str]:
        out = set(self._edges)
        out.update(e.parent for e in self._edges.values())
        return out
