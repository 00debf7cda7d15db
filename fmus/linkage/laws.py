"""Prescribed motion laws for drivers: angle, rate and acceleration as functions of time.

A driver constrains an angle (of a body, or between two bodies) to ``f(t)``.  A law
given by its angular velocity is integrated here in closed form, so every driver
is holonomic and can be enforced at position level like any other constraint.

Every law is a small frozen dataclass whose call returns ``(f, f', f'')`` in
rad, rad/s, rad/s^2.  Laws are configuration, not state: they are never copied
by ``get_state``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ConstantSpeed:
    """theta(t) = angle0 + speed (t - start_time)  (rad, rad/s, s)."""

    angle0: float = 0.0
    speed: float = 0.0
    start_time: float = 0.0

    def __call__(self, t: float) -> tuple[float, float, float]:
        return self.angle0 + self.speed * (t - self.start_time), self.speed, 0.0


@dataclass(frozen=True)
class CosineRampSpeed:
    """Angular velocity w(t) = speed (1 - cos(pi t / ramp_time)) / 2 for t < ramp_time,
    ``speed`` after (t measured from ``start_time``); the angle starts at angle0.

    With speed = 2 pi and ramp_time = 1 this is the seed's crank law (section 4.2.1):
    w(t) = 2 pi (1 - cos(pi t)) / 2 for t < 1 s and 2 pi rad/s after.
    """

    angle0: float = 0.0
    speed: float = 2.0 * math.pi
    ramp_time: float = 1.0
    start_time: float = 0.0

    def __call__(self, t: float) -> tuple[float, float, float]:
        tau = t - self.start_time
        T, w = self.ramp_time, self.speed
        if tau <= 0.0:
            return self.angle0, 0.0, 0.0
        if tau < T:
            k = math.pi / T
            angle = self.angle0 + 0.5 * w * (tau - math.sin(k * tau) / k)
            return angle, 0.5 * w * (1.0 - math.cos(k * tau)), 0.5 * w * k * math.sin(k * tau)
        return self.angle0 + 0.5 * w * T + w * (tau - T), w, 0.0


@dataclass(frozen=True)
class SineAngle:
    """theta(t) = angle0 + amplitude sin(2 pi frequency t + phase)  (rad, Hz)."""

    angle0: float = 0.0
    amplitude: float = 0.0
    frequency: float = 1.0
    phase: float = 0.0

    def __call__(self, t: float) -> tuple[float, float, float]:
        w = 2.0 * math.pi * self.frequency
        s, c = math.sin(w * t + self.phase), math.cos(w * t + self.phase)
        a = self.amplitude
        return self.angle0 + a * s, a * w * c, -a * w * w * s
