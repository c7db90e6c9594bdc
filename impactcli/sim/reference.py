"""Reference trajectories x1_ref (motor side, after reduction) and their derivatives.

Every generator returns ``(pos, vel, acc)``, each (N, n) [rad, rad/s, rad/s²], at the
sample times ``t`` (N,) [s]. Smooth families (multi-sine, fade-in included) have analytic
derivatives. Triangle families are position triangles = velocity steps, as in the paper's
experiments: their velocity is analytic (piecewise constant) and their acceleration is
what a controller at period Ts sees, the backward difference of the velocity — an
impulse of height Δv/Ts at each corner sample. Point-to-point moves use a trapezoidal
velocity (acceleration steps; position and velocity continuous).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Arrays = tuple[np.ndarray, np.ndarray, np.ndarray]


def _diff_acc(vel: np.ndarray, ts: float) -> np.ndarray:
    acc = np.zeros_like(vel)
    acc[1:] = np.diff(vel, axis=0) / ts
    return acc


def _tri(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit triangle of phase p (cycles): -1 at p = 0, +1 at p = 0.5; and its slope."""
    f = np.mod(p, 1.0)
    up = f < 0.5
    val = np.where(up, 4 * f - 1, 3 - 4 * f)
    slope = np.where(up, 4.0, -4.0)
    return val, slope


@dataclass(frozen=True)
class Triangle:
    """Position triangle per joint: center ± amplitude [rad], period [s], phase [cycles]."""

    center: tuple[float, ...]
    amplitude: tuple[float, ...]
    period_s: tuple[float, ...]
    phase: tuple[float, ...] | None = None

    def generate(self, t: np.ndarray, ts: float, rng: np.random.Generator) -> Arrays:
        n = len(self.center)
        ph = self.phase if self.phase is not None else (0.25,) * n
        pos = np.empty((t.size, n))
        vel = np.empty((t.size, n))
        for j in range(n):
            v, s = _tri(t / self.period_s[j] + ph[j])
            pos[:, j] = self.center[j] + self.amplitude[j] * v
            vel[:, j] = self.amplitude[j] * s / self.period_s[j]
        return pos, vel, _diff_acc(vel, ts)


@dataclass(frozen=True)
class FMTriangle:
    """Frequency-modulated triangle: instantaneous frequency f0 (1 + depth sin(2π t / T_mod)).

    f0 = 1 / period_s per joint; depth in [0, 1); mod_period_s [s].
    """

    center: tuple[float, ...]
    amplitude: tuple[float, ...]
    period_s: tuple[float, ...]
    depth: float = 0.5
    mod_period_s: float = 20.0

    def generate(self, t: np.ndarray, ts: float, rng: np.random.Generator) -> Arrays:
        n = len(self.center)
        pos = np.empty((t.size, n))
        vel = np.empty((t.size, n))
        wm = 2 * math.pi / self.mod_period_s
        for j in range(n):
            f0 = 1.0 / self.period_s[j]
            phase = f0 * t - f0 * self.depth / wm * (np.cos(wm * t) - 1.0) + 0.25
            freq = f0 * (1.0 + self.depth * np.sin(wm * t))
            v, s = _tri(phase)
            pos[:, j] = self.center[j] + self.amplitude[j] * v
            vel[:, j] = self.amplitude[j] * s * freq
        return pos, vel, _diff_acc(vel, ts)


@dataclass(frozen=True)
class PointToPoint:
    """Synchronised point-to-point moves between random targets, trapezoidal velocity.

    Targets are drawn uniformly in [low, high] per joint (from the scenario's seed); each
    move lasts the longest time any joint needs under max_vel [rad/s] and max_acc
    [rad/s²] with a quarter of the move accelerating and a quarter decelerating; then the
    arm dwells dwell_s [s]. The first move starts from ``start``.
    """

    start: tuple[float, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    max_vel: tuple[float, ...]
    max_acc: tuple[float, ...]
    dwell_s: float = 0.5

    def generate(self, t: np.ndarray, ts: float, rng: np.random.Generator) -> Arrays:
        n = len(self.start)
        pos = np.empty((t.size, n))
        vel = np.zeros((t.size, n))
        acc = np.zeros((t.size, n))
        cur = np.asarray(self.start, dtype=np.float64)
        pos[:] = cur
        t_move = 0.0
        lo, hi = np.asarray(self.low), np.asarray(self.high)
        vmax, amax = np.asarray(self.max_vel), np.asarray(self.max_acc)
        t_end = float(t[-1]) if t.size else 0.0
        while t_move <= t_end:
            target = rng.uniform(lo, hi)
            d = target - cur
            # normalised profile: ramps of 1/4 each, peak speed 4/3 D/T, accel 16/3 D/T²
            dur = float(np.max(np.maximum(np.abs(d) * (4 / 3) / vmax,
                                          np.sqrt(np.abs(d) * (16 / 3) / amax))))
            dur = max(dur, 4 * ts)
            sel = (t >= t_move) & (t < t_move + dur)
            tau = (t[sel] - t_move) / dur
            s, sd, sdd = _trap_profile(tau)
            pos[sel] = cur + np.outer(s, d)
            vel[sel] = np.outer(sd / dur, d)
            acc[sel] = np.outer(sdd / dur**2, d)
            after = t >= t_move + dur
            pos[after] = target
            vel[after] = 0.0
            acc[after] = 0.0
            cur = target
            t_move += dur + self.dwell_s
        return pos, vel, acc


def _trap_profile(tau: np.ndarray) -> Arrays:
    """Normalised trapezoid: s(0) = 0, s(1) = 1; ramps over [0, 1/4] and [3/4, 1]."""
    a = 16.0 / 3.0
    vp = 4.0 / 3.0
    s = np.empty_like(tau)
    sd = np.empty_like(tau)
    sdd = np.empty_like(tau)
    r1 = tau < 0.25
    r3 = tau >= 0.75
    r2 = ~r1 & ~r3
    s[r1] = 0.5 * a * tau[r1] ** 2
    sd[r1] = a * tau[r1]
    sdd[r1] = a
    s[r2] = 0.5 * a * 0.0625 + vp * (tau[r2] - 0.25)
    sd[r2] = vp
    sdd[r2] = 0.0
    rem = 1.0 - tau[r3]
    s[r3] = 1.0 - 0.5 * a * rem**2
    sd[r3] = a * rem
    sdd[r3] = -a
    return s, sd, sdd


@dataclass(frozen=True)
class MultiSine:
    """Sum of n_sines sines per joint, random frequencies in [f_min, f_max] Hz and phases.

    Peak deviation from center ≤ amplitude [rad]; a quintic smoothstep fade-in over fade_s
    [s] (zero first and second derivatives at both ends) starts the motion from rest with
    a continuous acceleration.
    """

    center: tuple[float, ...]
    amplitude: tuple[float, ...]
    f_min: float = 0.1
    f_max: float = 1.0
    n_sines: int = 4
    fade_s: float = 2.0

    def generate(self, t: np.ndarray, ts: float, rng: np.random.Generator) -> Arrays:
        n = len(self.center)
        pos = np.empty((t.size, n))
        vel = np.empty((t.size, n))
        acc = np.empty((t.size, n))
        # fade-in window and its derivatives
        x = np.clip(t / self.fade_s, 0.0, 1.0)
        inside = t < self.fade_s
        big_t = self.fade_s
        wv = np.where(inside, x**3 * (10 - 15 * x + 6 * x**2), 1.0)
        wd = np.where(inside, 30 * x**2 * (1 - x) ** 2 / big_t, 0.0)
        wdd = np.where(inside, 60 * x * (1 - x) * (1 - 2 * x) / big_t**2, 0.0)
        for j in range(n):
            f = rng.uniform(self.f_min, self.f_max, self.n_sines)
            ph = rng.uniform(0, 2 * math.pi, self.n_sines)
            a = np.full(self.n_sines, self.amplitude[j] / self.n_sines)
            w = 2 * math.pi * f
            arg = np.outer(t, w) + ph
            y = np.sin(arg) @ a
            yd = np.cos(arg) @ (a * w)
            ydd = -np.sin(arg) @ (a * w * w)
            pos[:, j] = self.center[j] + wv * y
            vel[:, j] = wd * y + wv * yd
            acc[:, j] = wdd * y + 2 * wd * yd + wv * ydd
        return pos, vel, acc


@dataclass(frozen=True)
class Waypoints:
    """Piecewise-linear position through (times [s], positions (K, n) [rad]): velocity steps.

    Before the first time the position is the first waypoint; after the last, the last.
    """

    times: tuple[float, ...]
    positions: tuple[tuple[float, ...], ...]

    def generate(self, t: np.ndarray, ts: float, rng: np.random.Generator) -> Arrays:
        tp = np.asarray(self.times, dtype=np.float64)
        xp = np.asarray(self.positions, dtype=np.float64)
        n = xp.shape[1]
        pos = np.empty((t.size, n))
        vel = np.zeros((t.size, n))
        seg = np.clip(np.searchsorted(tp, t, side="right") - 1, 0, tp.size - 2)
        inside = (t >= tp[0]) & (t < tp[-1])
        for j in range(n):
            pos[:, j] = np.interp(t, tp, xp[:, j])
            dt = np.diff(tp)
            slope = np.divide(np.diff(xp[:, j]), dt, out=np.zeros(dt.size), where=dt > 0)
            vel[inside, j] = slope[seg[inside]]
        return pos, vel, _diff_acc(vel, ts)


Reference = Triangle | FMTriangle | PointToPoint | MultiSine | Waypoints
