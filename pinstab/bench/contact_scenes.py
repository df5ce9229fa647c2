"""The closed-form contact scenes of the contacts benchmark: their exact motions and the error metrics
every simulator's samples are scored with (``benchmarks/contacts``).

Samples (:class:`ObjectSamples`) are the scene's one free body: times, centre position, linear and
angular velocity, all in world axes, whatever the simulator. The metrics use only what a sampled
trajectory shows, so that every simulator is scored the same way:

* creep: the largest displacement of the centre in the plane of the contact (or along the sliding
  direction) from the first sample [m];
* a slide: the relative error of the displacement along the slope at the last sample;
* sphere-spin: t*, the first sample at which the slip velocity ``v_x - r w_y`` of the lowest point is
  below ``SLIP_FLOOR`` of its start, and v*, the centre's speed at the last sample;
* bouncing-ball: each apex from a flight sample by energy, ``gap + v_z^2 / (2 g)`` (exact in flight),
  at the last rising sample before it; the rest time, the first sample after which the ball's vertical
  speed stays below ``REST_SPEED``.

A time-stepper is sampled at every step, so that its t* and rest time are what it resolves (within a
step); an event-driven simulator reports these times as located events, and is scored on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

GRAVITY = 9.81  # [m/s^2]
BALL_RADIUS = 0.05  # [m] bouncing-ball
PINCH_BLOCK = 0.05  # [m] side of the pinch's cube
PINCH_FINGER_MASS = 0.1  # [kg]
SLIP_FLOOR = 1e-4  # [-] of the initial slip velocity: below it the sphere rolls
REST_SPEED = 1e-3  # [m/s] below it (and staying so) the ball rests
APEXES = 5


@dataclass(frozen=True)
class ObjectSamples:
    """The free body's samples, world axes.

    Attributes:
        t: times [s] (n). position: the centre [m] (n, 3). velocity: the centre's [m/s] (n, 3).
        angular: [rad/s] (n, 3).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    angular: np.ndarray


def free_flyer_samples(model: pin.Model, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> ObjectSamples:
    """The samples of a Pinocchio model's one free-flyer joint (its velocity is in the body's axes: turned
    to world axes here).

    Raises:
        ValueError: the model has no free-flyer joint.
    """
    joint = next(j for j in model.joints if j.shortname() == "JointModelFreeFlyer")
    position = q[:, joint.idx_q : joint.idx_q + 3]
    velocity, angular = np.empty_like(position), np.empty_like(position)
    for k in range(len(t)):
        rotation = pin.Quaternion(q[k, joint.idx_q + 3 : joint.idx_q + 7]).toRotationMatrix()
        velocity[k] = rotation @ v[k, joint.idx_v : joint.idx_v + 3]
        angular[k] = rotation @ v[k, joint.idx_v + 3 : joint.idx_v + 6]
    return ObjectSamples(np.asarray(t, dtype=float), position.copy(), velocity, angular)


# -- closed forms -----------------------------------------------------------------------------------------
def slide_distance(theta: float, mu: float, t: float) -> float:
    """A block released from rest on an incline of ``theta`` [rad] with friction ``mu``: its displacement
    down the slope at ``t`` [s] [m] (0 when it sticks, mu >= tan theta)."""
    return max(GRAVITY * (math.sin(theta) - mu * math.cos(theta)), 0.0) * t**2 / 2


def rolling_onset(v0: float, omega0: float, mu: float, radius: float) -> tuple[float, float]:
    """sphere-spin: (t* [s] when sliding ends, v* [m/s] the rolling speed) of a solid sphere thrown at
    ``v0`` [m/s] with backspin ``omega0`` [rad/s]."""
    return 2 * (v0 + radius * omega0) / (7 * mu * GRAVITY), (5 * v0 - 2 * radius * omega0) / 7


def bounce(height: float, restitution: float) -> tuple[np.ndarray, float]:
    """bouncing-ball: (the apex gaps e^(2k) h, k = 1 .. APEXES [m]; the rest time t0 (1 + e)/(1 - e) [s])."""
    t0 = math.sqrt(2 * height / GRAVITY)
    apexes = height * restitution ** (2 * np.arange(1, APEXES + 1))
    return apexes, t0 * (1 + restitution) / (1 - restitution)


def pinch_drop(mu: float, squeeze: float, mass: float, t: float) -> float:
    """pinch: the block's fall [m] at ``t`` [s] from rest when two fingers squeeze it with ``squeeze`` [N]
    each: 0 if 2 mu F >= m g (it holds), else (g - 2 mu F / m) t^2 / 2."""
    return max(GRAVITY - 2 * mu * squeeze / mass, 0.0) * t**2 / 2


# -- metrics ----------------------------------------------------------------------------------------------
def creep(samples: ObjectSamples, axes: tuple[int, ...]) -> float:
    """The largest displacement [m] of the centre from its first sample along the world ``axes``."""
    moved = samples.position[:, axes] - samples.position[0, axes]
    return float(np.max(np.linalg.norm(moved, axis=1)))


def relative_error(value: float, exact: float) -> float:
    """|value - exact| / |exact| [-]."""
    return abs(value - exact) / abs(exact)


def slip_end(samples: ObjectSamples, radius: float) -> float:
    """t* [s]: the first sample at which the slip velocity of a ball's lowest point along x,
    ``v_x - r w_y``, is below SLIP_FLOOR of the start's (a time-stepper's samples: its steps).

    Raises:
        ValueError: the ball never stops sliding.
    """
    slip = samples.velocity[:, 0] - radius * samples.angular[:, 1]
    rolling = np.flatnonzero(np.abs(slip) <= SLIP_FLOOR * abs(slip[0]))
    if not len(rolling):
        raise ValueError("the ball is still sliding at the last sample")
    return float(samples.t[rolling[0]])


def apex_gaps(samples: ObjectSamples, radius: float) -> np.ndarray:
    """The apex gaps [m], in order, by energy ``gap + v_z^2 / (2 g)`` at the last rising sample before
    each apex (a sample whose vertical velocity is > 0 and the next one's <= 0)."""
    gap, rising = samples.position[:, 2] - radius, samples.velocity[:, 2]
    tops = np.flatnonzero((rising[:-1] > 0) & (rising[1:] <= 0))
    return gap[tops] + rising[tops] ** 2 / (2 * GRAVITY)


def rest_time(samples: ObjectSamples) -> float:
    """The first sample time [s] after which the ball's vertical speed stays below REST_SPEED.

    Raises:
        ValueError: it does not come to rest within the samples.
    """
    moving = np.flatnonzero(np.abs(samples.velocity[:, 2]) > REST_SPEED)
    if len(moving) and moving[-1] == len(samples.t) - 1:
        raise ValueError("the ball is still moving at the last sample")
    return float(samples.t[moving[-1] + 1 if len(moving) else 0])
