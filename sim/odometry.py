"""Wheel-encoder odometry with slip noise that grows with speed and turning (a Wiener-process model).

Per integration step the encoders measure the commanded wheel motion: a
distance ``ds`` [m] and a turn ``dθ`` [rad] over ``dt`` [s], at speeds
v = |ds|/dt and ω = |dθ|/dt. The odometry integrates them with independent
zero-mean Gaussian errors whose *variances* grow linearly with the motion,
so the error statistics do not depend on the step size:

    var(e_s) = m · [(K_S0 + K_SV · v) · |ds| + K_SW · |dθ|]      [m²]
    var(e_θ) = m · [(K_T0 + K_TW · ω) · |dθ| + K_TS · |ds|]      [rad²]

``m`` is the slip multiplier of the floor under the robot (1, or a
low-friction patch's ``slip``). Hence, driving straight at constant v for a
distance s, the along-track error has variance m·(K_S0 + K_SV·v)·s and the
heading error m·K_TS·s; turning in place through an angle φ at constant ω,
the heading error has variance m·(K_T0 + K_TW·ω)·|φ|. The integration is
the exact arc (midpoint heading). Not modelled: systematic wheel-radius or
track errors (zero-mean only), and a gyro (Kobuki can fuse one; the thesis's
drift came from the wheels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2

K_S0 = 1.0e-4  # [m] along-track variance per metre travelled
K_SV = 5.0e-4  # [s] … extra per metre, per m/s of speed
K_SW = 1.0e-5  # [m²/rad] along-track variance per radian turned
K_T0 = 5.0e-4  # [rad] heading variance per radian turned
K_TW = 1.0e-3  # [rad·s] … extra per radian, per rad/s of turn rate
K_TS = 3.0e-4  # [rad²/m] heading variance per metre travelled


@dataclass(frozen=True)
class SlipModel:
    """The six coefficients of the model above (defaults: the module constants)."""

    k_s0: float = K_S0
    k_sv: float = K_SV
    k_sw: float = K_SW
    k_t0: float = K_T0
    k_tw: float = K_TW
    k_ts: float = K_TS

    def variances(self, ds: float, dth: float, dt: float, m: float = 1.0) -> tuple[float, float]:
        """(var e_s [m²], var e_θ [rad²]) for one step of ``ds`` [m], ``dth`` [rad] over ``dt`` [s]."""
        a_s, a_t = abs(ds), abs(dth)
        v, w = (a_s / dt, a_t / dt) if dt > 0 else (0.0, 0.0)
        var_s = m * ((self.k_s0 + self.k_sv * v) * a_s + self.k_sw * a_t)
        var_t = m * ((self.k_t0 + self.k_tw * w) * a_t + self.k_ts * a_s)
        return var_s, var_t


def arc(pose: Pose2, ds: float, dth: float) -> Pose2:
    """``pose`` moved by ``ds`` [m] along an arc turning ``dth`` [rad] (exact for constant v, ω)."""
    if abs(dth) < 1e-9:
        chord = ds
    else:
        chord = 2.0 * ds / dth * math.sin(dth / 2.0)
    h = pose.theta + dth / 2.0
    return Pose2(pose.x + chord * math.cos(h), pose.y + chord * math.sin(h), wrap_angle(pose.theta + dth))


class WheelOdometry:
    """Integrates encoder increments with slip noise into the pose of base_link in ``odom``."""

    def __init__(self, rng: np.random.Generator, model: SlipModel | None = None):
        self.rng = rng
        self.model = model or SlipModel()
        self.pose = Pose2()
        self.v = 0.0  # [m/s] last measured speed
        self.omega = 0.0  # [rad/s]

    def update(self, ds: float, dth: float, dt: float, slip: float = 1.0) -> Pose2:
        """Add one step of measured wheel motion; returns the new odometry pose."""
        var_s, var_t = self.model.variances(ds, dth, dt, slip)
        e0, e1 = self.rng.standard_normal(2).tolist()
        ds_m = ds + math.sqrt(var_s) * e0
        dth_m = dth + math.sqrt(var_t) * e1
        self.pose = arc(self.pose, ds_m, dth_m)
        if dt > 0:
            self.v, self.omega = ds_m / dt, dth_m / dt
        return self.pose
