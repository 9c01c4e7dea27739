"""Time parametrisation of joint paths under velocity, acceleration and jerk limits (ruckig).

Method (path–velocity decomposition):

1. Each waypoint gets a path coordinate ``s``: joint-space arc length, or one the caller gives (the
   executor uses the TCP's Cartesian arc length, so a cap on ṡ is a TCP speed).
2. The joint path becomes a C² piecewise-cubic curve q(s), so that jerk stays finite:
   - the cubic spline through every waypoint (not-a-knot ends) — it follows the smooth path that a
     dense IK path samples, passing exactly through each waypoint; measured ≤ 0.3 mm from the
     Cartesian polyline at the TCP on fold segments (the tests bound it at 1 mm);
   - unless that spline would leave the range a joint's waypoints span (it overshoots at sharp
     corners): then a uniform cubic B-spline whose control points are the polyline resampled at
     uniform spacing h of ``s``, with reflected end points so it starts and ends exactly at the
     first and last waypoint. It lies in the convex hull of every four consecutive control points
     and cuts a corner turning by θ by ≈ h·θ/6 (h ≤ MAX_SPACING rad of joint travel).
   Either way no joint leaves the range its waypoints span, so the joint position limits that the
   waypoints respect are respected.
3. The chain rule gives each joint's velocity ``q'ṡ``, acceleration ``q''ṡ² + q's̈`` and jerk
   ``q'''ṡ³ + 3q''ṡs̈ + q's⃛``; the exact maxima of |q'|, |q''|, |q'''| over the curve turn the
   joint limits into bounds on ṡ, s̈, s⃛ under which no joint exceeds any limit anywhere.
4. Ruckig computes the time-optimal rest-to-rest profile of the scalar ``s`` under those bounds;
   it is sampled at the control period and mapped back through the curve.

The community edition of ruckig has no intermediate waypoints; running it on the scalar path
coordinate keeps the path shape (all joints move along the one curve) instead of letting each joint
take its own time-optimal route between waypoints. The bounds are global (the tightest spot of the
path sets them for all of it): exact and simple, close to optimal for the smooth, densely sampled IK
paths of fold segments, but a path with one sharp corner is slow all along.

A path that turns back on itself (two consecutive legs more than 90° apart in joint space: a lift
and a lowering at one place, as a pick-and-place whose place is its pick makes) has a kink no C²
curve follows at speed: as one curve, its 10 cm up and down took 134 s. There the arm must stop
anyway, so the path is split at each such cusp, each part parametrised rest to rest, and the parts
joined (2.6 s for that path).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory
from scipy.interpolate import CubicSpline

from foldbot.errors import ConfigError, require

LIMIT_MARGIN = 0.995
"""Fraction of every limit the plan uses, leaving room for floating-point round-off."""
MAX_SPACING = 0.05
"""Largest resampling spacing of the corner-cutting B-spline (rad of joint travel)."""
MAX_SPANS = 4000
"""Most spans the B-spline resamples one path into."""
MERGE = 1e-3
"""Waypoints closer than this fraction of the median waypoint spacing count as one."""
CUSP_COS = 0.0
"""Consecutive legs of the joint path whose cosine is below this (a turn of more than 90°) meet at
a cusp, where the trajectory comes to rest."""
OVERSHOOT = 1e-3
"""How far (rad) the spline through the waypoints may pass beyond the range a joint's waypoints span
(a smooth joint path peaks between its samples) before the corner-cutting B-spline replaces it."""

# Uniform cubic B-spline span: B(u) = [1, u, u², u³] · _BASIS · [Q0, Q1, Q2, Q3], u ∈ [0, 1].
_BASIS = (
    np.array(
        [
            [1.0, 4.0, 1.0, 0.0],
            [-3.0, 0.0, 3.0, 0.0],
            [3.0, -6.0, 3.0, 0.0],
            [-1.0, 3.0, -3.0, 1.0],
        ]
    )
    / 6.0
)


@dataclass(frozen=True)
class JointTrajectory:
    """A joint trajectory sampled every `dt` seconds from rest at the first sample to rest at the last."""

    times: np.ndarray
    """Sample times (T,), s, from 0 in steps of the control period."""
    positions: np.ndarray
    """Joint positions (T × dof), rad."""
    velocities: np.ndarray
    """Joint velocities (T × dof), rad/s."""
    accelerations: np.ndarray
    """Joint accelerations (T × dof), rad/s²."""
    arc: np.ndarray
    """Path coordinate reached at each sample (T,), in the units of time_parametrize's `arc` (joint
    arc length in rad by default); maps a sample back to the waypoints, e.g. for monitoring."""

    @property
    def duration(self) -> float:
        """Time of the last sample (s); the motion is at rest there."""
        return float(self.times[-1])

    @property
    def dt(self) -> float:
        """Sample period (s); 0 for a single-sample trajectory."""
        return float(self.times[1] - self.times[0]) if len(self.times) > 1 else 0.0

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, acceleration) at time `t` (s), linear between samples, held at the
        ends."""
        if not math.isfinite(t):
            raise ConfigError(f"sample time must be finite, got {t!r}")
        last = len(self.times) - 1
        if last == 0 or t <= 0.0:
            k, w = 0, 0.0
        elif t >= self.duration:
            k, w = last - 1, 1.0
        else:
            k = min(int(t / self.dt), last - 1)
            w = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        k1 = min(k + 1, last)

        def lerp(a: np.ndarray) -> np.ndarray:
            return (1.0 - w) * a[k] + w * a[k1]

        return lerp(self.positions), lerp(self.velocities), lerp(self.accelerations)

    def held(self, seconds: float, dt: float) -> JointTrajectory:
        """This trajectory, then still at its last sample for `seconds` (round(seconds / dt) more
        samples `dt` apart, at rest): a segment's dwell, as control.executor holds it."""
        require(
            math.isfinite(seconds) and seconds >= 0.0 and math.isfinite(dt) and dt > 0.0,
            f"a hold needs seconds ≥ 0 and a sample period > 0, got {seconds!r} and {dt!r}",
        )
        n = round(seconds / dt)
        if n == 0:
            return self
        zeros = np.zeros((n, self.positions.shape[1]))
        return JointTrajectory(
            times=np.concatenate([self.times, self.times[-1] + dt * np.arange(1, n + 1)]),
            positions=np.vstack([self.positions, np.repeat(self.positions[-1:], n, axis=0)]),
            velocities=np.vstack([self.velocities, zeros]),
            accelerations=np.vstack([self.accelerations, zeros]),
            arc=np.concatenate([self.arc, np.repeat(self.arc[-1:], n)]),
        )

    def peaks(self) -> dict[str, float]:
        """Largest |velocity|, |acceleration| and |jerk| (from the accelerations) over all joints."""
        jerk = 0.0
        if len(self.times) > 1:
            jerk = float(np.abs(np.diff(self.accelerations, axis=0)).max() / self.dt)
        return {
            "velocity": float(np.abs(self.velocities).max()),
            "acceleration": float(np.abs(self.accelerations).max()),
            "jerk": jerk,
        }


@dataclass(frozen=True)
class _Curve:
    """Piecewise cubic q(s): on [breaks[k], breaks[k+1]], q = Σ coef[k, i] · (s − breaks[k])^i."""

    breaks: np.ndarray  # (m + 1,)
    coef: np.ndarray  # (m, 4, dof)

    def evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, dq/ds, d²q/ds² at the coordinates `s` (T,)."""
        k = np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, len(self.coef) - 1)
        x = (s - self.breaks[k])[:, None]
        c = self.coef[k]
        q = c[:, 0] + x * (c[:, 1] + x * (c[:, 2] + x * c[:, 3]))
        dq = c[:, 1] + x * (2 * c[:, 2] + x * 3 * c[:, 3])
        ddq = 2 * c[:, 2] + 6 * c[:, 3] * x
        return q, dq, ddq

    def derivative_maxima(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact per-joint maxima of |dq/ds|, |d²q/ds²|, |d³q/ds³| over the curve."""
        c1, c2, c3 = self.coef[:, 1], self.coef[:, 2], self.coef[:, 3]
        w = np.diff(self.breaks)[:, None]
        d1 = np.maximum(np.abs(c1), np.abs(c1 + 2 * c2 * w + 3 * c3 * w**2))
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(c3 != 0.0, -c2 / (3 * c3), -1.0)  # vertex of the quadratic q'
        inside = (x > 0.0) & (x < w)
        d1 = np.maximum(d1, np.where(inside, np.abs(c1 + 2 * c2 * x + 3 * c3 * x**2), 0.0))
        d2 = np.maximum(np.abs(2 * c2), np.abs(2 * c2 + 6 * c3 * w))
        return d1.max(axis=0), d2.max(axis=0), np.abs(6 * c3).max(axis=0)

    def value_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Exact per-joint (min, max) of q over the curve."""
        c0, c1, c2, c3 = (self.coef[:, i] for i in range(4))
        w = np.diff(self.breaks)[:, None]
        ends = np.concatenate([c0, c0 + w * (c1 + w * (c2 + w * c3))])
        lo, hi = ends.min(axis=0), ends.max(axis=0)
        disc = c2**2 - 3 * c3 * c1  # roots of q' = c1 + 2c2 x + 3c3 x²
        for sign in (-1.0, 1.0):
            with np.errstate(divide="ignore", invalid="ignore"):
                x = np.where(
                    np.abs(c3) > 1e-300,
                    (-c2 + sign * np.sqrt(np.maximum(disc, 0.0))) / (3 * c3),
                    np.where(np.abs(c2) > 1e-300, -c1 / (2 * c2), -1.0),
                )
            ok = (disc >= 0.0) & (x > 0.0) & (x < w)
            val = c0 + x * (c1 + x * (c2 + x * c3))
            lo = np.minimum(lo, np.where(ok, val, np.inf).min(axis=0))
            hi = np.maximum(hi, np.where(ok, val, -np.inf).max(axis=0))
        return lo, hi


def _limits(values: np.ndarray | list[float], dof: int, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float).reshape(-1)
    if arr.shape == (1,):
        arr = np.full(dof, arr[0])
    if arr.shape != (dof,):
        raise ConfigError(f"{what} must have {dof} values (one per joint), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ConfigError(f"{what} must be finite and > 0, got {arr.tolist()}")
    return arr


def _bounds(values: np.ndarray | list[float], dof: int, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float).reshape(-1)
    if arr.shape != (dof,) or np.isnan(arr).any():
        raise ConfigError(f"{what} position limits must be {dof} numbers, got {values!r}")
    return arr


def _check_path(path: np.ndarray | list) -> np.ndarray:
    arr = np.asarray(path, dtype=float)
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ConfigError(f"joint path must be an N × dof array with N ≥ 1, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ConfigError(
            f"joint path must be finite, got {float(arr[i, j])!r} at waypoint {i}, joint {j}"
        )
    return arr


def _check_arc(arc: np.ndarray | list | None, path: np.ndarray) -> np.ndarray:
    """The path coordinate of every waypoint from 0: `arc` checked, or joint-space arc length."""
    joint = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if arc is None:
        return joint
    out = np.asarray(arc, dtype=float).reshape(-1)
    if out.shape != (len(path),):
        raise ConfigError(
            f"arc must give one path coordinate per waypoint ({len(path)}), got shape {out.shape}"
        )
    if not np.all(np.isfinite(out)) or np.any(np.diff(out) < 0.0):
        raise ConfigError(f"arc must be finite and non-decreasing, got {out.tolist()}")
    out = out - out[0]
    if joint[-1] > 1e-12 and out[-1] <= 1e-12:
        return joint  # the joints move but the coordinate does not (e.g. a pure re-orientation)
    return out


def _distinct(path: np.ndarray, arc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The waypoints with duplicates merged: a waypoint closer than MERGE × the median waypoint
    spacing (in coordinate) to the last one kept, or at the same joint angles, is dropped (the
    one before it at the end of the path), so the coordinate strictly increases and both ends
    stay exact. Such near-duplicates (an IK start point repeated, the start replaced by where the
    arm really is) would otherwise put a needless kink into the curve."""
    legs = np.diff(arc)
    tol = MERGE * float(np.median(legs[legs > 0.0]))
    kept = [0]
    for i in range(1, len(path)):
        last = kept[-1]
        if arc[i] - arc[last] > tol and np.any(path[i] != path[last]):
            kept.append(i)
        elif i == len(path) - 1:  # the end is exact: it replaces the last one kept
            if len(kept) > 1:
                kept[-1] = i
            else:
                kept.append(i)
    return path[kept], arc[kept]


def _cusps(path: np.ndarray) -> list[int]:
    """Indices of the interior waypoints (of distinct waypoints) where the path turns back: the
    legs before and after more than 90° apart (CUSP_COS)."""
    legs = np.diff(path, axis=0)
    norms = np.linalg.norm(legs, axis=1)
    cos = np.einsum("ij,ij->i", legs[:-1], legs[1:]) / (norms[:-1] * norms[1:])
    return [int(i) + 1 for i in np.flatnonzero(cos < CUSP_COS)]


def _joined(parts: list[JointTrajectory], starts: list[float]) -> JointTrajectory:
    """Trajectories that each end where the next begins, at rest, run one after another: each
    one's first sample (the last one's last) dropped, its times and path coordinate (from 0)
    moved on to where the previous one ended (`starts`: each part's coordinate on the whole
    path)."""
    first, rest = parts[0], parts[1:]
    offsets = np.cumsum([part.duration for part in parts[:-1]])

    def stacked(field: str) -> np.ndarray:
        return np.vstack([getattr(first, field), *(getattr(p, field)[1:] for p in rest)])

    return JointTrajectory(
        times=np.concatenate(
            [first.times, *(p.times[1:] + t for p, t in zip(rest, offsets, strict=True))]
        ),
        positions=stacked("positions"),
        velocities=stacked("velocities"),
        accelerations=stacked("accelerations"),
        arc=np.concatenate(
            [first.arc + starts[0], *(p.arc[1:] + s for p, s in zip(rest, starts[1:], strict=True))]
        ),
    )


def _interpolating_curve(path: np.ndarray, arc: np.ndarray) -> _Curve:
    """The C² cubic spline through every waypoint (not-a-knot ends; a line for two)."""
    if len(path) == 2:
        coef = np.zeros((1, 4, path.shape[1]))
        coef[0, 0], coef[0, 1] = path[0], (path[1] - path[0]) / arc[1]
        return _Curve(arc.copy(), coef)
    spline = CubicSpline(arc, path, axis=0)
    return _Curve(arc.copy(), np.transpose(spline.c[::-1], (1, 0, 2)).copy())


def _smoothing_curve(path: np.ndarray, arc: np.ndarray) -> _Curve:
    """Uniform cubic B-spline on the polyline resampled at uniform coordinate spacing (≈ the
    median waypoint spacing, at most MAX_SPACING rad of joint travel), interpolating both ends."""
    legs = np.diff(arc)
    length = float(arc[-1])
    joint_legs = np.linalg.norm(np.diff(path, axis=0), axis=1)
    spacing = min(
        float(np.median(legs)),
        MAX_SPACING * float(np.min(legs / np.maximum(joint_legs, 1e-300))),
    )
    n = int(np.clip(math.ceil(length / spacing - 1e-9), 1, MAX_SPANS))
    h = length / n
    s = np.linspace(0.0, length, n + 1)
    ctrl = np.column_stack([np.interp(s, arc, path[:, j]) for j in range(path.shape[1])])
    ctrl[0], ctrl[-1] = path[0], path[-1]
    ext = np.vstack([2 * ctrl[0] - ctrl[1], ctrl, 2 * ctrl[-1] - ctrl[-2]])
    windows = np.stack([ext[k : k + 4] for k in range(n)])  # n × 4 × dof
    coef = np.einsum("ab,kbd->kad", _BASIS, windows) / (h ** np.arange(4))[None, :, None]
    return _Curve(s, coef)


def _joint_curve(
    path: np.ndarray, arc: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None
) -> _Curve:
    """The C² curve the trajectory follows: the spline through the waypoints, or the corner-cutting
    B-spline where that spline would overshoot a joint's waypoint range by more than OVERSHOOT
    or leave its position limits."""
    pts, s = _distinct(path, arc)
    curve = _interpolating_curve(pts, s)
    lo, hi = curve.value_range()
    ok = np.all(lo >= path.min(axis=0) - OVERSHOOT) and np.all(hi <= path.max(axis=0) + OVERSHOOT)
    if lower is not None and upper is not None:
        ok = ok and np.all(lo >= lower) and np.all(hi <= upper)
    return curve if ok else _smoothing_curve(pts, s)


def _ratio(num: np.ndarray, den: np.ndarray) -> float:
    """min over joints of num / den, joints with den = 0 left out (inf if none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.min(np.where(den > 0, num / den, np.inf)))


def _profile(length: float, v: float, a: float, j: float) -> Trajectory:
    """Ruckig's time-optimal rest-to-rest profile of a scalar over `length` under v, a, j."""
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.target_position = [length]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
    profile = Trajectory(1)
    result = Ruckig(1).calculate(inp, profile)
    if result not in (Result.Working, Result.Finished):  # pragma: no cover - ruckig failure
        raise ConfigError(
            f"ruckig could not time-parametrise a path of length {length!r} under "
            f"v={v!r}, a={a!r}, j={j!r}: {result}"
        )
    return profile


def _fastest_profile(
    curve: _Curve,
    length: float,
    vel: np.ndarray,
    acc: np.ndarray,
    jerk: np.ndarray,
    max_speed: float,
) -> Trajectory:
    """The fastest profile of s whose bounds on ṡ, s̈, s⃛ keep every joint within its limits.

    With d1, d2, d3 the maxima of |q'|, |q''|, |q'''| per joint, any bounds v, a, j on ṡ, s̈, s⃛
    with d1·v ≤ vel, d2·v² + d1·a ≤ acc and d3·v³ + 3·d2·v·a + d1·j ≤ jerk are safe. How the
    budget is split between the path's curvature and the profile's own acceleration is searched
    over a small grid of (v, a); the shortest ruckig profile is kept.
    """
    d1, d2, d3 = curve.derivative_maxima()
    v_top = min(
        max_speed,
        _ratio(vel, d1),
        0.95 * _ratio(acc, d2) ** 0.5,
        0.95 * _ratio(jerk, d3) ** (1 / 3),
    )
    best: Trajectory | None = None
    for v in v_top * 0.8 ** np.arange(12):
        a_top = _ratio(acc - d2 * v**2, d1)
        for a in a_top * np.array([1.0, 0.8, 0.6, 0.4, 0.2]):
            j = 0.999 * _ratio(jerk - d3 * v**3 - 3 * d2 * v * a, d1)
            if not (j > 0.0 and math.isfinite(a) and math.isfinite(j)):
                continue
            profile = _profile(length, float(v), float(a), j)
            if best is None or profile.duration < best.duration:
                best = profile
    assert best is not None  # the smallest (v, a) always leaves jerk budget
    return best


def time_parametrize(
    path: np.ndarray,
    vel_limits: np.ndarray,
    acc_limits: np.ndarray,
    jerk_limits: np.ndarray,
    dt: float,
    speed_scale: float = 1.0,
    arc: np.ndarray | None = None,
    max_arc_speed: float | None = None,
    position_limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> JointTrajectory:
    """Time-optimal jerk-limited trajectory along the joint waypoints `path` (N × dof), rest to rest.

    Never exceeds `vel_limits`·`speed_scale`, `acc_limits` or `jerk_limits` (per joint, rad/s,
    rad/s², rad/s³), sampled every `dt` s; starts exactly at path[0] and ends exactly at path[-1].
    `speed_scale` ∈ (0, 1] caps the joint velocities at that fraction of their limits. `arc` (N,)
    is an optional non-decreasing coordinate of the waypoints along the path (default: joint-space
    arc length; e.g. the TCP's Cartesian arc length) and `max_arc_speed` caps its rate (e.g. a
    TCP speed in m/s). With `position_limits` (lower, upper), rad, the trajectory stays within
    them; without, within the range each joint's waypoints span (to OVERSHOOT). ConfigError names
    any bad input.
    """
    path = _check_path(path)
    dof = path.shape[1]
    vel = _limits(vel_limits, dof, "velocity limits")
    acc = _limits(acc_limits, dof, "acceleration limits")
    jerk = _limits(jerk_limits, dof, "jerk limits")
    if not (math.isfinite(dt) and dt > 0.0):
        raise ConfigError(f"control period dt must be a positive number of seconds, got {dt!r}")
    if not (math.isfinite(speed_scale) and 0.0 < speed_scale <= 1.0):
        raise ConfigError(f"speed_scale must be in (0, 1], got {speed_scale!r}")
    if max_arc_speed is not None and not (math.isfinite(max_arc_speed) and max_arc_speed > 0.0):
        raise ConfigError(f"max_arc_speed must be > 0, got {max_arc_speed!r}")
    coord = _check_arc(arc, path)
    lower = upper = None
    if position_limits is not None:
        lower, upper = (
            _bounds(b, dof, what)
            for b, what in zip(position_limits, ("lower", "upper"), strict=True)
        )
        outside = (path < lower - 1e-9) | (path > upper + 1e-9)
        if outside.any():
            i, j = np.argwhere(outside)[0]
            raise ConfigError(
                f"waypoint {i} has joint {j} at {path[i, j]:.6g} rad, outside its position limits "
                f"[{lower[j]:.6g}, {upper[j]:.6g}]"
            )

    if float(np.abs(path - path[0]).max()) <= 1e-12 or coord[-1] <= 1e-12:
        zero = np.zeros((1, dof))
        return JointTrajectory(np.zeros(1), path[-1:].copy(), zero, zero.copy(), coord[-1:].copy())
    pts, s_pts = _distinct(path, coord)
    cusps = _cusps(pts)
    if cusps:
        bounds = [0, *cusps, len(pts) - 1]
        parts = [
            time_parametrize(
                pts[i : k + 1],
                vel,
                acc,
                jerk,
                dt,
                speed_scale,
                arc=s_pts[i : k + 1],
                max_arc_speed=max_arc_speed,
                position_limits=position_limits,
            )
            for i, k in itertools.pairwise(bounds)
        ]
        return _joined(parts, [float(s_pts[i]) for i in bounds[:-1]])

    curve = _joint_curve(path, coord, lower, upper)
    s_end = float(coord[-1])
    profile = _fastest_profile(
        curve,
        s_end,
        LIMIT_MARGIN * speed_scale * vel,
        LIMIT_MARGIN * acc,
        LIMIT_MARGIN * jerk,
        math.inf if max_arc_speed is None else max_arc_speed,
    )

    n = max(1, math.ceil(profile.duration / dt - 1e-9))
    times = np.arange(n + 1) * dt
    state = np.array([profile.at_time(min(t, profile.duration)) for t in times])[:, :, 0]
    s = np.clip(state[:, 0], 0.0, s_end)
    sd, sdd = state[:, 1], state[:, 2]
    s[-1], sd[-1], sdd[-1] = s_end, 0.0, 0.0

    q, dq, ddq = curve.evaluate(s)
    qd = dq * sd[:, None]
    qdd = ddq * sd[:, None] ** 2 + dq * sdd[:, None]
    if lower is not None and upper is not None:
        q = np.clip(q, lower, upper)  # round-off only: the curve's exact range is within them
    q[0], q[-1] = path[0], path[-1]
    qd[0] = qd[-1] = qdd[0] = qdd[-1] = 0.0
    return JointTrajectory(times, q, qd, qdd, s)


def thin_samples(
    times: np.ndarray, period: float, velocities: np.ndarray | None = None
) -> np.ndarray:
    """Indices of the samples at `times` (s, increasing) to keep so that they lie at least
    `period` s apart, the first and the last always among them: a trajectory for a driver that
    splines between its points (ros_control's controllers), which need not take every control
    step's sample. With `velocities` (N × dof), where the arm comes to rest or sets off (a
    sample at rest beside one moving) is kept too, so a rest between motions stays exact."""
    t = np.asarray(times, dtype=float)
    require(
        t.ndim == 1 and len(t) >= 1 and bool(np.all(np.diff(t) > 0)),
        "sample times must be a non-empty, strictly increasing 1-D array",
    )
    require(math.isfinite(period) and period >= 0.0, f"period must be ≥ 0 s, got {period!r}")
    must = {0, len(t) - 1}
    if velocities is not None:
        rest = np.all(np.asarray(velocities, dtype=float) == 0.0, axis=1)
        edge = rest & (np.r_[False, ~rest[:-1]] | np.r_[~rest[1:], False])
        must |= {int(i) for i in np.flatnonzero(edge)}
    keep = [0]
    for i in range(1, len(t)):
        if i in must or (t[i] - t[keep[-1]] >= period - 1e-9 and t[-1] - t[i] >= period / 2):
            keep.append(i)
    return np.array(keep, dtype=int)


def hermite_resample(
    times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, grid: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities at `grid` (s) on the cubic Hermite spline through the samples
    (each span's cubic matches both ends' positions and velocities), as ros_control's joint
    trajectory controller interpolates points that carry positions and velocities."""
    from scipy.interpolate import CubicHermiteSpline

    spline = CubicHermiteSpline(np.asarray(times, float), positions, velocities, axis=0)
    g = np.clip(np.asarray(grid, float), times[0], times[-1])
    return spline(g), spline.derivative()(g)


def commands_at_steps(
    times: np.ndarray, pos: np.ndarray, vel: np.ndarray, dt: float, splined: bool
) -> tuple[np.ndarray, np.ndarray]:
    """A trajectory's commanded joints and velocities at each physics step after its start
    (`dt` s apart, to its last point's time): its own samples where they lie on those steps (as
    the planner sends them); else `splined` (points with velocities, as ros_control's
    controller splines them) on cubic Hermite spans, or interpolated linearly."""
    n = round(times[-1] / dt)
    if len(times) == n + 1 and np.allclose(times, np.arange(n + 1) * dt, atol=1e-6):
        return pos[1:], vel[1:]
    grid = np.arange(1, n + 1) * dt
    if splined:
        return hermite_resample(times, pos, vel, grid)
    cols = range(pos.shape[1])
    q_cmd = np.column_stack([np.interp(grid, times, pos[:, j]) for j in cols])
    v_cmd = np.column_stack([np.interp(grid, times, vel[:, j]) for j in cols])
    return q_cmd, v_cmd
