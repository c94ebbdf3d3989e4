"""Kobuki odometry: heading from the gyro, distance from the wheel encoders with slip (kobuki_node, use_imu_heading).

The real Kobuki's odometry (kobuki_node, ``use_imu_heading: true``, its
default) takes its heading from the factory-calibrated single-axis gyro and
its position from the wheel encoders along that heading. Modelled per
integration step of a commanded motion ``ds`` [m], ``dθ`` [rad] over ``dt`` [s]
(v = |ds|/dt):

* encoders, a Wiener-process slip model whose variance grows linearly with
  the motion, so its statistics do not depend on the step size::

      var(e_s) = m · [(K_S0 + K_SV · v) · |ds| + K_SW · |dθ|]      [m²]

  ``m`` is the slip multiplier of the floor under the robot (1, or a
  low-friction patch's ``slip``): patches make the distance worse, not the
  heading;
* gyro: the integrated heading is ``dθ·(1 + s) + b·dt + GYRO_NOISE·√dt·n``
  with white noise ``n``, a rate bias ``b`` ~ N(0, GYRO_BIAS_SIGMA²) and a
  scale error ``s`` ~ N(0, GYRO_SCALE_SIGMA²), both drawn once per power-up
  (one :class:`WheelOdometry`).

Hence, driving straight at constant v for a distance s in a time t, the
along-track error has variance m·(K_S0 + K_SV·v)·s and the heading error
GYRO_NOISE²·t + GYRO_BIAS_SIGMA²·t² (over power-ups); turning in place
through φ in t, GYRO_NOISE²·t + GYRO_BIAS_SIGMA²·t² + GYRO_SCALE_SIGMA²·φ².
The constants are the robot's documented facts (:mod:`homing.robot.turtlebot`),
which the estimators assume too. The integration is the exact arc
(midpoint heading). Not modelled: systematic wheel-radius errors (zero-mean
slip only), gyro saturation (110°/s on the real part; navigation turns slower).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import (
    GYRO_BIAS_SIGMA,
    GYRO_NOISE,
    GYRO_SCALE_SIGMA,
    ODOM_K_S0,
    ODOM_K_SV,
    ODOM_K_SW,
)
from homing.robot.types import Pose2

K_S0 = ODOM_K_S0  # [m] along-track variance per metre travelled
K_SV = ODOM_K_SV  # [s] … extra per metre, per m/s of speed
K_SW = ODOM_K_SW  # [m²/rad] along-track variance per radian turned


@dataclass(frozen=True)
class SlipModel:
    """The encoder slip coefficients and the gyro's errors (defaults: the robot's documented facts)."""

    k_s0: float = K_S0
    k_sv: float = K_SV
    k_sw: float = K_SW
    gyro_noise: float = GYRO_NOISE  # [rad/√s]
    gyro_bias_sigma: float = GYRO_BIAS_SIGMA  # [rad/s]
    gyro_scale_sigma: float = GYRO_SCALE_SIGMA

    def variances(self, ds: float, dth: float, dt: float, m: float = 1.0) -> tuple[float, float]:
        """(var e_s [m²], var of the gyro's white noise [rad²]) for one step of ``ds`` [m], ``dth`` [rad] over ``dt`` [s]."""
        a_s, a_t = abs(ds), abs(dth)
        v = a_s / dt if dt > 0 else 0.0
        var_s = m * ((self.k_s0 + self.k_sv * v) * a_s + self.k_sw * a_t)
        return var_s, self.gyro_noise**2 * max(dt, 0.0)


def arc(pose: Pose2, ds: float, dth: float) -> Pose2:
    """``pose`` moved by ``ds`` [m] along an arc turning ``dth`` [rad] (exact for constant v, ω)."""
    if abs(dth) < 1e-9:
        chord = ds
    else:
        chord = 2.0 * ds / dth * math.sin(dth / 2.0)
    h = pose.theta + dth / 2.0
    return Pose2(pose.x + chord * math.cos(h), pose.y + chord * math.sin(h), wrap_angle(pose.theta + dth))


class WheelOdometry:
    """Integrates encoder distance and gyro heading into the pose of base_link in ``odom``.

    The gyro's bias [rad/s] and scale error are drawn from ``rng`` once, here
    (a power-up); every step then draws the encoder slip and the gyro noise.
    """

    def __init__(self, rng: np.random.Generator, model: SlipModel | None = None):
        self.rng = rng
        self.model = model or SlipModel()
        b, s = self.rng.standard_normal(2).tolist()
        self.gyro_bias = self.model.gyro_bias_sigma * b  # [rad/s]
        self.gyro_scale = self.model.gyro_scale_sigma * s
        self.pose = Pose2()
        self.v = 0.0  # [m/s] last measured speed
        self.omega = 0.0  # [rad/s] last gyro rate

    def update(self, ds: float, dth: float, dt: float, slip: float = 1.0, turned: float | None = None) -> Pose2:
        """Add one step of wheel motion ``ds`` [m], ``dth`` [rad] over ``dt`` [s]; returns the new pose.

        ``turned`` [rad] is the body's real turn when it differs from the
        wheels' (pushed round by the dock's guide): the gyro measures that.
        """
        var_s, var_g = self.model.variances(ds, dth, dt, slip)
        e0, e1 = self.rng.standard_normal(2).tolist()
        ds_m = ds + math.sqrt(var_s) * e0
        rate_turn = dth if turned is None else turned
        dth_m = rate_turn * (1.0 + self.gyro_scale) + self.gyro_bias * max(dt, 0.0) + math.sqrt(var_g) * e1
        self.pose = arc(self.pose, ds_m, dth_m)
        if dt > 0:
            self.v, self.omega = ds_m / dt, dth_m / dt
        return self.pose
