"""Time parameterisation of geometric paths with TOPP-RA (toppra), optionally wrist-aware.

``time_parameterize`` runs time-optimal path parameterisation under the arm's joint velocity
and acceleration limits (``spec.arm.max_velocity``, ``spec.arm.max_acceleration``) over a
cubic spline through the path waypoints, parameterised by joint-space arc length.

The **wrist-aware** variant adds the wrist's velocity limit. Along a
path ``q(s)`` the tool base turns at ``ω = J_ω(q) q'(s) ṡ``, so the leveling rates of
Eqs. 4.5–4.7 are linear in the path speed: ``q̇_wrist = A(s) ṡ`` with
``A(s) = J⁺(θ(s)) (ω_corr(s) × u(s))`` per unit ``ṡ`` (``ω_corr = −Rᵀ J_ω q'``). The constraint
``|A_j(s)| ṡ ≤ q̇max_j`` is a bound on ``x = ṡ²`` per grid point, which toppra takes as a
first-order linear constraint — the result is feasible for the verifier by construction
(up to the margin between grid points, covered by ``wrist_velocity_margin``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

import numpy as np
import toppra
import toppra.constraint
from numpy.typing import NDArray
from toppra.constants import MAX_TRIES, SMALL, TINY
from toppra.solverwrapper.cy_seidel_solverwrapper import seidelWrapper

from articutool.planning.constraints import f0_leveling_angles
from articutool.tool.kinematics import joint_rates_for_rotation
from articutool.trajectory import JointTrajectory

__all__ = ["RETIME_SCALES", "WristSpeedConstraint", "retime", "time_parameterize",
           "toppra_speeds", "wrist_rate_profile"]

# toppra logs at INFO on every call; keep library output quiet.
toppra.setup_logging("WARNING")

SdotLimit = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def wrist_rate_profile(
    q: NDArray[np.float64],
    dq_ds: NDArray[np.float64],
    kinematics: Callable[[NDArray[np.float64], NDArray[np.float64]],
                         tuple[NDArray[np.float64], NDArray[np.float64]]],
    rcond: float,
) -> NDArray[np.float64]:
    """``A(s)`` (N, 2): leveling wrist rates per unit path speed at samples ``q(s)``.

    ``kinematics(q, qd) -> (R_F0 (N,3,3), ω (N,3))`` is ``ArmModel.tool_base_kinematics``.
    Evaluated on leveling branch A (Eqs. 4.2–4.3): the other branch ``(θp + π, π − θr)`` and
    whole-turn shifts give the same rates up to sign (``|cos θr|`` and the up vector are
    unchanged), so ``|A(s)|`` — all a speed limit needs — does not depend on which solution the
    wrist follows.
    """
    R, omega = kinematics(q, dq_ds)
    omega_local = -np.einsum("kji,kj->ki", R, omega)  # Eq. 4.5
    return joint_rates_for_rotation(f0_leveling_angles(R), omega_local, rcond)  # Eqs. 4.6–4.7


class WristSpeedConstraint(toppra.constraint.LinearConstraint):
    """toppra first-order constraint ``ṡ ≤ sdot_max(s)`` from a callback on the path.

    ``sdot_max(q (N, n), q' (N, n)) -> (N,)`` gives the largest path speed allowed at each
    grid point (``inf`` for no limit).
    """

    def __init__(self, dof: int, sdot_max: SdotLimit) -> None:
        super().__init__()
        self.dof = dof
        self._sdot_max = sdot_max
        self._format_string = "    Wrist leveling speed limit\n"

    def compute_constraint_params(self, path, gridpoints):
        q, dq = path(gridpoints), path(gridpoints, 1)
        sd = np.asarray(self._sdot_max(q, dq), dtype=np.float64)
        xb = np.empty((gridpoints.size, 2))
        xb[:, 0] = 0.0
        xb[:, 1] = np.minimum(sd, 1e8) ** 2
        return None, None, None, None, None, None, xb


def _const_accel(
    ss: NDArray[np.float64], v: NDArray[np.float64]
) -> tuple[NDArray[np.float64], Callable[[NDArray[np.float64]], NDArray[np.float64]],
           Callable[[NDArray[np.float64]], NDArray[np.float64]]]:
    """The path speed ``v`` (at grid points ``ss``) under constant path acceleration between
    grid points, as toppra's ``ParametrizeConstAccel`` defines it, evaluated vectorised:
    the grid's times, and ``s(t)`` and ``ṡ(t)``. Same arithmetic, in the same order, as
    toppra's per-sample loop (bit-identical samples)."""
    ds = ss[1:] - ss[:-1]
    x = v ** 2
    u = 0.5 * (x[1:] - x[:-1]) / ds
    ts = np.concatenate([[0.0], np.cumsum(2 * ds / (v[:-1] + v[1:]))])

    def where(t: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        i = np.searchsorted(ts, t, side="right") - 1
        i[i == u.size] -= 1
        return i, t - ts[i]

    def s_of_t(t: NDArray[np.float64]) -> NDArray[np.float64]:
        i, dt = where(t)
        return ss[i] + dt * v[i] + 0.5 * dt ** 2 * u[i]

    def sd_of_t(t: NDArray[np.float64]) -> NDArray[np.float64]:
        i, dt = where(t)
        return v[i] + dt * u[i]

    return ts, s_of_t, sd_of_t


def toppra_speeds(
    constraints: Sequence[toppra.constraint.LinearConstraint],
    path: toppra.SplineInterpolator,
    gridpoints: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """Path speeds ``ṡ`` at ``gridpoints`` of the time-optimal rest-to-rest parameterisation:
    ``toppra.algorithm.TOPPRA(constraints, path, gridpoints).compute_parameterization(0, 0)``
    with the solver it picks for linear constraints (toppra's Cython ``seidelWrapper``), its
    ``sd_vec``; ``None`` where it reports a failure.

    The same solver calls with the same arguments in the same order and the same arithmetic
    between them as toppra's backward (controllable sets) and forward passes, so the same
    speeds bit for bit (``tests/test_planning.py``); without the per-stage NumPy temporaries,
    NaN scans and logger checks of toppra's Python loop and without its search for optional
    solver packages on every call, which together cost about twice as much as the solves.
    """
    solver = seidelWrapper(list(constraints), path, gridpoints, solve_lp1d=True)
    solve = solver.solve_stagewise_optim
    n = solver.get_no_stages()
    nan = math.nan
    # Backward pass: K[i] = [lo[i], hi[i]], the squared speeds at stage i from which rest
    # at the end stays reachable (ReachabilityAlgorithm.compute_controllable_sets, sd_end 0).
    lo, hi = [0.0] * (n + 1), [0.0] * (n + 1)
    g_max = np.zeros(solver.get_no_vars())
    g_max[0], g_max[1] = 1e-9, -1.0
    g_min = -g_max
    solver.setup_solver()
    for i in range(n - 1, -1, -1):
        a, b = lo[i + 1], hi[i + 1]
        x_hi = solve(i, None, g_max, nan, nan, a, b)[1]
        x_lo = solve(i, None, g_min, nan, nan, a, b)[1]
        if x_lo < 0:
            x_lo = 0.0
        if x_lo != x_lo or x_hi != x_hi:  # NaN
            return None  # toppra: FailUncontrollable
        lo[i], hi[i] = x_lo, x_hi
    solver.close_solver()
    if lo[0] > SMALL or hi[0] + SMALL < 0.0:  # toppra: x_start + SMALL < K[0, 0] or …
        return None  # rest at the start is not controllable
    # Forward pass: the largest controllable speed at every stage (TOPPRA._forward_step and
    # the loop of compute_parameterization, sd_start 0, with its retries).
    deltas = solver.get_deltas().tolist()
    xs = [0.0] * (n + 1)
    g = np.zeros(solver.get_no_vars())
    g[1] = -1.0
    tries = 0
    solver.setup_solver()
    i = 0
    while i < n:
        x = xs[i]
        g[0] = -2 * deltas[i]
        a, b = lo[i + 1], hi[i + 1]
        u = solve(i, None, g, x, x, a, b)[0]
        if u != u:  # NaN: toppra retries from a slightly lower speed
            if tries >= MAX_TRIES:
                return None  # toppra: ErrUnknown
            xs[i] = max(x - TINY, 0.999 * x)
            tries += 1
            continue
        tries = 0
        x_next = x + 2 * deltas[i] * u
        # toppra's max(x_next - TINY, 0.9999 * x_next), then min(b, max(a, that)), spelled
        # out as the builtins decide (a NaN gives a)
        p, q = x_next - TINY, 0.9999 * x_next
        x_next = q if q > p else p
        m = x_next if x_next > a else a
        xs[i + 1] = m if m < b else b
        i += 1
    solver.close_solver()
    sd = np.sqrt(np.array(xs))
    return None if np.isnan(sd).any() else sd


@functools.lru_cache(maxsize=16)
def _joint_limit_constraints(
    vmax: tuple[float, ...], amax: tuple[float, ...]
) -> tuple[toppra.constraint.LinearConstraint, ...]:
    """toppra's joint velocity and acceleration constraints, built once per limit set (~0.4 ms
    each time otherwise); toppra only reads them, so plans can share them."""
    v, a = np.asarray(vmax), np.asarray(amax)
    return (
        toppra.constraint.JointVelocityConstraint(np.stack([-v, v], axis=1)),
        toppra.constraint.JointAccelerationConstraint(
            np.stack([-a, a], axis=1),
            discretization_scheme=toppra.constraint.DiscretizationType.Interpolation,
        ),
    )


def time_parameterize(
    waypoints: NDArray[np.float64],
    joint_names: Sequence[str],
    max_velocity: NDArray[np.float64],
    max_acceleration: NDArray[np.float64],
    *,
    sdot_max: SdotLimit | None = None,
    grid_step: float = 0.01,
    dt: float = 0.02,
) -> JointTrajectory | None:
    """Time-optimal trajectory through ``waypoints`` (N, n) under velocity/acceleration limits.

    The path is a cubic spline through the waypoints over joint-space arc length (dense
    waypoints keep it on the planned polyline); TOPP-RA runs on grid points ``grid_step`` rad
    of arc apart; the result is sampled every ``dt`` s (plus the end) with positions and
    velocities, starting and ending at rest. ``sdot_max`` adds :class:`WristSpeedConstraint`.
    Returns ``None`` when TOPP-RA finds no parameterisation.
    """
    wp = np.asarray(waypoints, dtype=np.float64)
    seg = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    wp = wp[keep]
    if wp.shape[0] < 2:
        return None
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(wp, axis=0), axis=1))])
    path = toppra.SplineInterpolator(s, wp, bc_type="natural")
    n = wp.shape[1]
    constraints = list(_joint_limit_constraints(
        tuple(np.asarray(max_velocity, dtype=np.float64).tolist()),
        tuple(np.asarray(max_acceleration, dtype=np.float64).tolist())))
    if sdot_max is not None:
        constraints.append(WristSpeedConstraint(n, sdot_max))
    grid = np.linspace(0.0, s[-1], max(int(np.ceil(s[-1] / grid_step)) + 1, 20))
    sd = toppra_speeds(constraints, path, grid)
    if sd is None:
        return None
    ts, s_of_t, sd_of_t = _const_accel(grid, sd)
    T = float(ts[-1])
    if not np.isfinite(T) or T <= 0:
        return None
    t = np.linspace(0.0, T, max(int(np.ceil(T / dt)), 1) + 1)
    s_t, sd_t = s_of_t(t), sd_of_t(t)
    q = np.asarray(path(s_t))
    qd = np.asarray(path(s_t, 1)) * sd_t[:, None]
    q[0], q[-1] = wp[0], wp[-1]
    qd[0], qd[-1] = 0.0, 0.0
    return JointTrajectory(tuple(joint_names), t, q, qd)


# Speed scales tried in turn to make a transport spill-free: 0.8ⁿ down to a quarter of the
# arm's speed (four times the duration, sixteen times less acceleration).
RETIME_SCALES = (1.0, 0.8, 0.64, 0.51, 0.41, 0.33, 0.26)


def retime(traj: JointTrajectory, max_velocity: NDArray[np.float64],
           max_acceleration: NDArray[np.float64], scale: float) -> JointTrajectory | None:
    """The same path as ``traj`` (its samples as waypoints, in its joint order) timed by
    TOPP-RA at ``scale`` × the velocity limits and ``scale²`` × the acceleration limits — a
    trajectory ``1/scale`` times slower wherever the limits bind. ``None`` if TOPP-RA finds
    no parameterisation."""
    if not (math.isfinite(scale) and 0.0 < scale <= 1.0):
        raise ValueError(f"scale must be in (0, 1]; got {scale}")
    return time_parameterize(traj.positions, traj.joint_names,
                             np.asarray(max_velocity) * scale,
                             np.asarray(max_acceleration) * scale * scale)
