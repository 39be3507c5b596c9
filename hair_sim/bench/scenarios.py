"""Scripted head motions (quaternion xyzw per time) for tests, benchmarks and the demo driver."""

import math

import numpy as np


def quat_from_euler(roll, pitch, yaw):
    """Return the quaternion (x, y, z, w) of intrinsic z-y-x (yaw, pitch, roll) angles."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def smoothstep(x):
    """Return the C1 ramp 0 -> 1 on [0, 1] (zero speed at both ends)."""
    x = min(1.0, max(0.0, x))
    return x * x * (3.0 - 2.0 * x)


def violent(t):
    """Fast nods and shakes (about 11 rad/s peak yaw rate) with a bob: (position, quat)."""
    yaw = 0.6 * math.sin(2 * math.pi * 3.0 * t)
    pitch = 0.35 * math.sin(2 * math.pi * 2.5 * t + 0.7)
    roll = 0.15 * math.sin(2 * math.pi * 1.3 * t)
    pos = np.array([0.02 * math.sin(2 * math.pi * 1.7 * t), 0.0,
                    0.03 * math.sin(2 * math.pi * 2.0 * t)])
    return pos, quat_from_euler(roll, pitch, yaw)


def demo(t):
    """Calm demo motion: nods, turns and a walking bob, repeating every 12 s."""
    u = t % 12.0
    yaw = 0.7 * math.sin(2 * math.pi * u / 6.0) if u < 6.0 else 0.0
    pitch = 0.25 * math.sin(2 * math.pi * 1.0 * u) * (u >= 6.0) * smoothstep((u - 6.0) / 0.5) \
        * smoothstep((12.0 - u) / 0.5)
    bob = 0.015 * abs(math.sin(2 * math.pi * 0.9 * t))
    sway = 0.01 * math.sin(2 * math.pi * 0.45 * t)
    return np.array([0.0, sway, bob]), quat_from_euler(0.0, pitch, yaw)


# s between the demo's wind gusts (hair_sim_head_driver sends one this often)
GUST_PERIOD = 2.0


def demo_gust(k):
    """
    Return the demo's k-th gust (k >= 1): (velocity m/s, world frame), turbulence, seed.

    Calm on every third; otherwise 1.5-4 m/s, turning 0.7 rad from one gust to the next.
    """
    speed = 0.0 if k % 3 == 0 else 1.5 + 2.5 * abs(math.sin(k))
    angle = 0.7 * k
    return np.array([speed * math.cos(angle), speed * math.sin(angle), 0.0]), 0.3, k


def quarter_turn(t0, duration=0.3):
    """Return the motion of a 90 degree yaw from t0 over `duration` s (smoothstep), then held."""
    def motion(t):
        return np.zeros(3), quat_from_euler(0.0, 0.0,
                                            math.pi / 2 * smoothstep((t - t0) / duration))
    return motion


def drive(sim, motion, t0, duration, dt, every=None):
    """Feed `motion(t)` poses to sim and step it from t0 for duration; call every(sim)."""
    n = int(round(duration / dt))
    for i in range(n):
        t = t0 + (i + 1) * dt
        p, q = motion(t)
        sim.set_head_pose(t, p, q)
        sim.step(dt)
        if every is not None:
            every(sim)
    return t0 + n * dt
