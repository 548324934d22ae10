"""Wheel odometry that lost its sign, found and repaired from the recorded velocity.

Some robots' odometry integrates the *speed* instead of the velocity: backing up, the pose
still moves forward along the heading. A filter reading it carries the robot forward by what
it backed up (twice the distance off). CARMEN's ``ODOM`` lines record the translational
velocity ``tv`` beside the pose, with its sign, so such a log says so itself: while ``tv`` is
negative its poses keep moving forward. (fr079's raw log is one: 392 of its 410 ``ODOM``
increments recorded at ``tv < -0.02 m/s`` move forward, none backward; intel's and aces' logs
record ``tv = 0`` throughout and are left alone.)

:func:`check_sign` decides from the ``ODOM`` lines; :func:`signed_poses` repairs a pose
sequence (the scans' odometry poses) by giving each increment's translation the sign, and the
share, of the velocity over its interval: with ``tv_i`` the velocities of the ``ODOM`` lines
between two scans, the increment's translation in the robot's frame is multiplied by
``sum(tv_i) / sum(|tv_i|)`` (1 going forward, -1 backing up, in between when the robot
changed direction between the scans). Rotations are kept. docs/real-data.md, "fr079 raw's
odometry has no sign", has the measurements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ceamcl.pose import relative_poses

#: An ``ODOM`` line says the robot is backing up below this velocity (m/s).
REVERSING_TV = -0.02
#: A pose increment counts as a move when its forward component exceeds this (m).
MOVE_M = 1e-3
#: Fewest moves while backing up before the log's sign can be judged.
MIN_REVERSING = 10
#: Share of those moves that go forward for the odometry to count as unsigned.
UNSIGNED_SHARE = 0.9

__all__ = ["SignCheck", "check_sign", "forward_steps", "signed_poses"]


@dataclass(frozen=True)
class SignCheck:
    """What the ``ODOM`` lines say: of the ``reversing`` pose increments recorded while the
    velocity was below :data:`REVERSING_TV` (and that moved), ``forward`` moved forward."""

    reversing: int
    forward: int

    @property
    def unsigned(self) -> bool:
        return self.reversing >= MIN_REVERSING and self.forward >= UNSIGNED_SHARE * self.reversing

    def summary(self) -> str:
        return (
            f"the odometry has no sign ({self.forward} of the {self.reversing} ODOM increments "
            "recorded while backing up move forward): each scan's increment takes the sign of "
            "the recorded velocity"
        )


def forward_steps(poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each increment's translation along the heading it starts from."""
    return relative_poses(poses[:-1], poses[1:])[:, 0]


def _finite(tv: NDArray[np.float64]) -> NDArray[np.float64]:
    """A velocity that is not a number says nothing: 0."""
    return np.where(np.isfinite(tv), tv, 0.0)


def check_sign(
    odom_t: NDArray[np.float64], odom_poses: NDArray[np.float64], odom_tv: NDArray[np.float64]
) -> SignCheck:
    """Does the odometry keep moving forward while its velocity says the robot backs up?"""
    if odom_poses.shape[0] < 2 or not np.isfinite(odom_t).all():
        return SignCheck(0, 0)
    order = np.argsort(odom_t, kind="stable")
    poses, tv = odom_poses[order], _finite(odom_tv[order])
    fwd = forward_steps(poses)
    moved = (tv[1:] < REVERSING_TV) & (np.abs(fwd) > MOVE_M)
    return SignCheck(int(moved.sum()), int((fwd[moved] > 0.0).sum()))


def signed_poses(
    times: NDArray[np.float64],
    poses: NDArray[np.float64],
    odom_t: NDArray[np.float64],
    odom_tv: NDArray[np.float64],
) -> tuple[NDArray[np.float64], int]:
    """``poses`` (at ``times``, increasing) re-summed from the first with each increment's
    translation scaled by the velocity's sign share over its interval (module docstring), the
    headings as they are; and how many increments changed direction. An interval without an
    ``ODOM`` line takes the sign of the velocity interpolated at its middle."""
    n = poses.shape[0]
    if n < 2 or odom_t.size == 0 or not (np.isfinite(poses).all() and np.isfinite(odom_t).all()):
        return poses.copy(), 0  # one NaN pose would spread to every later one: left alone
    order = np.argsort(odom_t, kind="stable")
    ot, tv = odom_t[order], _finite(odom_tv[order])
    # lines with ot <= times[k] are ot[:idx[k]]; interval k covers (times[k-1], times[k]]
    idx = np.searchsorted(ot, times, side="right")
    c_tv = np.concatenate([[0.0], np.cumsum(tv)])
    c_abs = np.concatenate([[0.0], np.cumsum(np.abs(tv))])
    a, b = idx[:-1], idx[1:]
    total, speed = c_tv[b] - c_tv[a], c_abs[b] - c_abs[a]
    mid = np.interp(0.5 * (times[:-1] + times[1:]), ot, tv)
    fallback = np.where(mid < 0.0, -1.0, 1.0)
    share = np.where(speed > 0.0, total / np.where(speed > 0.0, speed, 1.0), fallback)
    # The headings are kept, so scaling an increment's translation in the robot's frame
    # scales it in the world's: the positions are re-summed from the first.
    d = np.diff(poses[:, :2], axis=0) * share[:, None]
    out = poses.copy()
    out[1:, :2] = poses[0, :2] + np.cumsum(d, axis=0)
    changed = int(np.count_nonzero((share < 0.0) & (np.abs(forward_steps(poses)) > MOVE_M)))
    return out, changed
