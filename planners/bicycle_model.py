"""The ego of the driving worlds as a deterministic planner model: the bicycle, its controllers, a compiled reward.

The ego knows its own state exactly and has no disturbance, so the planner's ego is a
*point*: `BicycleModel` predicts it with the compiled bicycle and controllers of
`minimaxplan.kernels.bicycle` (the ones the world's `bicycle_step` runs), so the
predicted trajectory equals the world's ego bit for bit under the same controls, and
all the uncertainty is in the reward's obstacle table (the other vehicles' forecast
boxes). The reward comes in through the compiled-reward protocol of
`minimaxplan.kernels` (a ``kernel_params`` with a registered `box_reward_minimum`, such
as `minimaxplan.scenarios.DrivingReward`'s), the road as `LaneGeometry` arrays: the
planners never import the scenarios.

A planner state is (x, y, v, psi, speed level, target lane, time) (`BicycleState`). An
action (`HIGHWAY_ACTIONS`, `TJUNCTION_ACTIONS`) changes the speed level and/or the
target lane; the controllers then act at every sub-step. `expand` steps every action
of a node over all sub-steps in one compiled call: the transition's reward is the
minimum of the reward over the sub-step states (as `PointModel`'s), terminal when one
of them collides. `fallback_values` (the planner's `FallbackModel` protocol) bounds
the return of holding one action from a state, which `RobustTreePlanner` adds to a
leaf's lower bound: the search then prefers plans after which braking (or keeping
the speed) stays collision-free over the whole forecast.

A model may carry a second reward, ``lane_keeping_reward``, for the paths of the
*lane-keeping family*: at most `LANE_KEEPING_PREFIX` decisions of actions that do not
change the target lane, then one such action held (`BicycleState.kept`). It is the
same reward on an obstacle table forecast for an ego that moves only along these
paths, which may be smaller (the other vehicles' behaviour depends on the ego's: a
vehicle beside it may not cut in). Transitions and held continuations of such paths
read it; every other transition reads ``reward``.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ..kernels import bicycle as bicycle_kernels
from ..kernels.bicycle import EgoController, LaneGeometry, apply_action, bicycle_step_one, ego_control_one
from ..kernels.box_primitives import maximum, minimum
from ..kernels.reward_protocol import (
    CompiledBoxReward,
    StateIndexedReward,
    box_reward_minimum,
    has_compiled_minimum,
    minimum_sources,
    sources_digest,
)
from ..models.errors import DimensionError, InputError
from ..models.validation import as_count, as_discount, as_finite_array, as_positive_scalar, check_instance

__all__ = [
    "HIGHWAY_ACTIONS",
    "TJUNCTION_ACTIONS",
    "HIGHWAY_TARGET_SPEEDS",
    "TJUNCTION_TARGET_SPEEDS",
    "BicycleState",
    "BicycleModel",
    "ego_controller",
    "MAX_FALLBACK_DECISIONS",
    "LANE_KEEPING_PREFIX",
    "MEMO_STATES",
    "RECORDED_DECISIONS",
]

#: The highway's actions (the paper's) as (name, speed-level change, lane change: +1 left, -1 right).
HIGHWAY_ACTIONS = (("LANE_LEFT", 0, 1), ("IDLE", 0, 0), ("LANE_RIGHT", 0, -1), ("FASTER", 1, 0), ("SLOWER", -1, 0))
#: The T-junction's actions: speed only, on the fixed left-turn route.
TJUNCTION_ACTIONS = (("SLOWER", -1, 0), ("IDLE", 0, 0), ("FASTER", 1, 0))
#: Target speeds of the speed levels, m/s.
HIGHWAY_TARGET_SPEEDS = (20.0, 25.0, 30.0)
TJUNCTION_TARGET_SPEEDS = (0.0, 4.5, 9.0)

#: Default controller gains (documented in `ego_controller`).
SPEED_GAIN = 1.0 / 0.6
STEERING_GAINS = (5.0, 8.33)
PURSUIT_TIME = 0.1
SPEED_EPSILON = 0.01


def ego_controller(
    lanes: LaneGeometry,
    target_speeds: Sequence[float],
    *,
    speed_gain: float = SPEED_GAIN,
    acceleration_bound: float = 6.0,
    steering_gains: Sequence[float] = STEERING_GAINS,
    pursuit_time: float = PURSUIT_TIME,
    speed_epsilon: float = SPEED_EPSILON,
    length: float = 5.0,
    max_speed: float = 40.0,
    max_steering: float = float(np.pi / 3),
    dt: float = 0.1,
) -> EgoController:
    """The ego's low-level controllers and bicycle (`minimaxplan.kernels.bicycle.EgoController`), checked.

    Parameters
    ----------
    lanes : LaneGeometry
        The road's lanes as arrays (`minimaxplan.scenarios.road.lane_geometry`, with the
        ego's route for the T-junction).
    target_speeds : sequence of float
        The speed levels' target speeds, m/s (`HIGHWAY_TARGET_SPEEDS` {20, 25, 30},
        `TJUNCTION_TARGET_SPEEDS` {0, 4.5, 9}), nondecreasing, >= 0.
    speed_gain : float
        k_v, 1/s: 1 / 0.6, highway-env's ``KP_A`` (the speed error decays with a 0.6 s
        time constant until the acceleration saturates).
    acceleration_bound : float
        a_bound, m/s^2 (6, the worlds' ``ego_acceleration_bound``: the controls stay
        admissible for `RoadWorld`).
    steering_gains : sequence of 2 float
        theta_b of the LinearVehicle steering law, fixed: (5, 8.33), the nominal gains
        of the other vehicles (highway-env's KP_HEADING and KP_HEADING * KP_LATERAL).
    pursuit_time : float
        tau, s (0.1, highway-env's TAU_PURSUIT).
    speed_epsilon : float
        The smallest speed in the steering features, m/s (0.01).
    length, max_speed, max_steering : float
        The bicycle (the worlds' `VehicleParameters`: 5 m, 40 m/s, pi / 3 rad).
    dt : float
        The sub-step, s (0.1).

    Returns
    -------
    EgoController

    Raises
    ------
    InputError
        If ``lanes`` is not a `LaneGeometry`, a gain or bound is not finite and
        positive, or the target speeds are negative or decreasing.
    DimensionError
        If ``steering_gains`` does not have length 2 or ``target_speeds`` is empty.
    """
    check_instance("lanes", lanes, LaneGeometry)
    speeds = as_finite_array("target_speeds", target_speeds)
    if speeds.ndim != 1 or speeds.size < 1:
        raise DimensionError(f"target_speeds must have shape (k,) with k >= 1, got shape {speeds.shape}")
    if np.any(speeds < 0) or np.any(np.diff(speeds) < 0):
        raise InputError(f"target_speeds must be >= 0 and nondecreasing, got {speeds.tolist()}")
    gains = as_finite_array("steering_gains", steering_gains, (2,))
    if max_steering >= np.pi / 2:
        raise InputError(f"max_steering must be < pi / 2, got {max_steering}")
    return EgoController(
        lanes=lanes,
        target_speeds=np.ascontiguousarray(speeds, dtype=float),
        speed_gain=as_positive_scalar("speed_gain", speed_gain),
        acceleration_bound=as_positive_scalar("acceleration_bound", acceleration_bound),
        theta_b=np.ascontiguousarray(gains, dtype=float),
        pursuit_time=as_positive_scalar("pursuit_time", pursuit_time, allow_zero=True),
        speed_epsilon=as_positive_scalar("speed_epsilon", speed_epsilon),
        length=as_positive_scalar("length", length),
        max_speed=as_positive_scalar("max_speed", max_speed),
        max_steering=as_positive_scalar("max_steering", max_steering),
        dt=as_positive_scalar("dt", dt),
    )


class BicycleState(NamedTuple):
    """A planner state of `BicycleModel`.

    Attributes
    ----------
    x : ndarray, shape (4,)
        ``(x, y, v, psi)`` (read-only).
    level : int
        The speed level (index of the target speed).
    lane : int
        The target lane (a lane index of the `LaneGeometry`).
    time : int
        The absolute sub-step index.
    keep_depth : int
        The decisions since the root along a path of the lane-keeping family (see the
        module docstring), -1 once the path has left it (a lane change took effect, or
        the action changed after the prefix).
    keep_hold : int
        The speed change + 1 of the action held after the prefix (0, 1, 2), -1 before.
    """

    x: np.ndarray
    level: int
    lane: int
    time: int
    keep_depth: int = 0
    keep_hold: int = -1

    @property
    def kept(self) -> bool:
        """Whether the path from the root is of the lane-keeping family (then ``lane_keeping_reward`` applies)."""
        return self.keep_depth >= 0


#: numba options of the ego kernels: cached on disk, no reference counting (see `_compile_without_refcounts`).
_NO_REFCOUNTS: dict[str, Any] = {"cache": True, "_nrt": False}


def _compile_without_refcounts(function, params_type: type):
    """``njit(cache=True, _nrt=False)`` with an on-disk index per params type (as `compile_per_params_type`).

    The kernels read the controller's and the reward's namedtuples in their inner
    loops; with numba's reference counting every such read costs an atomic increment
    and decrement (measured: 7x slower). They allocate nothing (the caller passes the
    scratch arrays), so they run without it, like `minimaxplan.planners.tree_ops`.
    """
    tag = hashlib.sha256(f"{params_type.__module__}.{params_type.__qualname__}".encode()).hexdigest()[:12]
    function.__qualname__ = f"{function.__qualname__}_{tag}"
    return njit(**_NO_REFCOUNTS)(function)


@functools.cache
def _expand_kernel(params_type: type):
    """The compiled expansion of every action of a node, for rewards of ``params_type``."""
    version = sources_digest(__file__, bicycle_kernels.__file__, *minimum_sources(params_type))

    def expand_actions(
        controller,
        params,
        x0,
        level,
        lane,
        time,
        speed_changes,
        lane_changes,
        substeps,
        z,
        out_x,
        out_meta,
        rewards,
        terminals,
    ):
        _ = version  # ties numba's cache entry to the sources it calls into
        half = controller.length / 2
        for a in range(speed_changes.shape[0]):
            lv, ln = apply_action(controller, level, lane, speed_changes[a], lane_changes[a])
            x, y, v, psi = x0[0], x0[1], x0[2], x0[3]
            worst = 1.0
            hit = False
            for k in range(substeps):
                accel, steer, ln = ego_control_one(controller, x, y, v, psi, lv, ln)
                x, y, v, psi = bicycle_step_one(x, y, v, psi, accel, steer, controller.dt, half, controller.max_speed)
                z[0], z[1], z[2], z[3] = -x, -y, -v, -psi
                z[4], z[5], z[6], z[7] = x, y, v, psi
                value, collided = box_reward_minimum(params, z, 4, float(time + k + 1))
                worst = minimum(worst, value)
                hit = hit or collided
            out_x[a, 0], out_x[a, 1], out_x[a, 2], out_x[a, 3] = x, y, v, psi
            out_meta[a, 0] = lv
            out_meta[a, 1] = ln
            rewards[a] = worst
            terminals[a] = hit

    return _compile_without_refcounts(expand_actions, params_type)


#: Decisions of lane-keeping actions of any kind before the lane-keeping family holds one
#: action (`BicycleModel`'s ``lane_keeping_reward``; the reach that its table is forecast
#: from enumerates 3^LANE_KEEPING_PREFIX prefixes, each continued by every held action).
LANE_KEEPING_PREFIX = 3

#: The values of `BicycleState.keep_hold`.
_KEEP_HOLDS = (-1, 0, 1, 2)

#: The most decisions a continuation is rolled out for (it stops earlier at the first terminal
#: transition, at the latest where the reward's obstacle table ends).
MAX_FALLBACK_DECISIONS = 10_000


#: The table a continuation reads (`fallback_values`): the reward's, or the lane-keeping one.
_REWARD_TABLE, _LANE_KEEPING_TABLE = 0, 1

#: The most states whose continuations a `BicycleModel` keeps (a search of K expansions
#: remembers K * n_actions of them); past it, it forgets them all.
MEMO_STATES = 4096


#: The longest continuation (in decisions) whose per-decision rewards are kept for the children
#: of its state (`BicycleModel.fallback_values`); a longer one is rolled out again by them.
RECORDED_DECISIONS = 32


@functools.cache
def _fallback_kernel(params_type: type):
    """The compiled continuation bounds of `BicycleModel.fallback_values`, for rewards of ``params_type``.

    For each row i of ``rows`` and action a of ``columns`` (indices into the states and the
    actions), the continuation holding a from state i is rolled out, its discounted
    return raises ``out[i]`` (which the caller zeroes), and its per-decision rewards are
    written to ``record[i, a]``, their number to ``recorded[i, a]`` when it ended at a
    terminal transition within `RECORDED_DECISIONS` decisions (else -1). A row reached
    from the parent state by action ``arrived_by[i]`` (-1: unknown) does not roll that
    action out again when the parent's own continuation of it (``parent_record[a,
    :parent_recorded[a]]``) was kept, is two decisions or more, and read the same table
    (``parent_tables[a] == tables[i, a]``): its rewards after the first decision are the
    row's, summed in the order the rollout sums them, so the value is the same to the last bit.
    """
    version = sources_digest(__file__, bicycle_kernels.__file__, *minimum_sources(params_type))

    def fallback_returns(
        controller,
        params,
        xs,
        levels,
        lanes,
        times,
        rows,
        columns,
        speed_changes,
        lane_changes,
        substeps,
        gamma,
        z,
        arrived_by,
        parent_record,
        parent_recorded,
        parent_tables,
        tables,
        record,
        recorded,
        out,
    ):
        _ = version  # ties numba's cache entry to the sources it calls into
        half = controller.length / 2
        capacity = record.shape[2]
        for i in rows:
            best = 0.0
            for a in columns:
                total = 0.0
                discount = 1.0
                if a == arrived_by[i] and parent_recorded[a] >= 2 and parent_tables[a] == tables[i, a]:
                    length = parent_recorded[a] - 1
                    for d in range(length):
                        worst = parent_record[a, d + 1]
                        total += discount * worst
                        discount *= gamma
                        record[i, a, d] = worst
                    recorded[i, a] = length
                    if total > best:
                        best = total
                    continue
                x, y, v, psi = xs[i, 0], xs[i, 1], xs[i, 2], xs[i, 3]
                level, lane, time = levels[i], lanes[i], times[i]
                recorded[i, a] = -1
                for decision in range(MAX_FALLBACK_DECISIONS):
                    level, lane = apply_action(controller, level, lane, speed_changes[a], lane_changes[a])
                    worst = 1.0
                    hit = False
                    for k in range(substeps):
                        accel, steer, lane = ego_control_one(controller, x, y, v, psi, level, lane)
                        x, y, v, psi = bicycle_step_one(
                            x, y, v, psi, accel, steer, controller.dt, half, controller.max_speed
                        )
                        z[0], z[1], z[2], z[3] = -x, -y, -v, -psi
                        z[4], z[5], z[6], z[7] = x, y, v, psi
                        value, collided = box_reward_minimum(params, z, 4, float(time + k + 1))
                        worst = minimum(worst, value)
                        hit = hit or collided
                    total += discount * worst
                    discount *= gamma
                    time += substeps
                    if decision < capacity:
                        record[i, a, decision] = worst
                    if hit:
                        if decision < capacity:
                            recorded[i, a] = decision + 1
                        break
                if total > best:
                    best = total
            out[i] = maximum(out[i], best)

    return _compile_without_refcounts(fallback_returns, params_type)


def _reward_params(name: str, reward: Any):
    """The compiled params of a reward argument, checked (`BicycleModel`)."""
    params = reward.kernel_params if isinstance(reward, CompiledBoxReward) else None
    if params is None or not has_compiled_minimum(params):
        raise InputError(
            f"{name} must expose kernel_params with a registered compiled box minimum "
            f"(minimaxplan.kernels.register_reward_params), got {type(reward).__name__}"
        )
    needed = reward.min_state_dim if isinstance(reward, StateIndexedReward) else None
    if needed is not None and needed > 4:
        raise DimensionError(f"{name} reads state coordinates up to index {needed - 1}, but the ego has 4 states")
    return params


class BicycleModel:
    """The ego as a deterministic `VectorisedModel` for `RobustTreePlanner` (see the module docstring).

    Parameters
    ----------
    controller : EgoController
        The bicycle and the controllers (`ego_controller`).
    reward : CompiledBoxReward
        A reward in [0, 1] over states ``(x, y, v, psi)`` whose ``kernel_params`` have a
        registered compiled box minimum (`minimaxplan.kernels.register_reward_params`),
        e.g. `minimaxplan.scenarios.DrivingReward`; evaluated on the degenerate boxes of
        the predicted sub-step states.
    actions : sequence of (str, int, int)
        ``(name, speed-level change, lane change)`` per action (`HIGHWAY_ACTIONS`,
        `TJUNCTION_ACTIONS`); the planner's actions are their indices.
    substeps : int
        Sub-steps per decision (5: 0.5 s at dt = 0.1 s).
    lane_keeping_reward : CompiledBoxReward, optional
        The reward of the transitions of the lane-keeping family's paths (states with
        ``kept``: at most `LANE_KEEPING_PREFIX` decisions of actions that keep the target
        lane, then one of them held), with the compiled params type of ``reward``: the
        same reward on an obstacle table forecast for an ego that moves only along such
        paths, which may be smaller (a vehicle beside the ego cannot cut in while the ego
        occupies its gap; see `minimaxplan.analysis.road_planning`). Its table must
        contain the obstacles for every trajectory of the family; ``reward``'s for every
        trajectory. None (the default): ``reward`` everywhere.

    Raises
    ------
    InputError
        If ``controller`` is not an `EgoController`, the reward has no registered
        compiled minimum, or an action is malformed.

    Notes
    -----
    The transition of action a from state (x, level, lane, t): ``(level', lane') =
    apply_action(level, lane, a)``, then ``substeps`` times the controllers' control and
    the bicycle step; reward ``min_k J(x_k, t + k)`` over the sub-step states k = 1 ..
    S, terminal when one of them is a zero case (collision, off road, or beyond the
    obstacle table). Deterministic: the same numbers as the world's ego under the same
    controls (`predict`).
    """

    def __init__(
        self,
        controller: EgoController,
        reward: Any,
        actions: Sequence,
        *,
        substeps: int = 5,
        lane_keeping_reward: Any = None,
    ) -> None:
        check_instance("controller", controller, EgoController)
        params = _reward_params("reward", reward)
        keep_params = None
        if lane_keeping_reward is not None:
            keep_params = _reward_params("lane_keeping_reward", lane_keeping_reward)
            if type(keep_params) is not type(params):
                raise InputError(
                    "lane_keeping_reward must have the kernel_params type of reward "
                    f"({type(params).__name__}), got {type(keep_params).__name__}"
                )
        try:
            table = [(str(name), int(ds), int(dl)) for name, ds, dl in actions]
        except (TypeError, ValueError):
            raise InputError(f"actions must be (name, speed change, lane change) triples, got {actions!r}") from None
        if not table or any(ds not in (-1, 0, 1) or dl not in (-1, 0, 1) for _, ds, dl in table):
            raise InputError(f"actions must be a non-empty sequence of changes in {{-1, 0, 1}}, got {actions!r}")
        self.controller = controller
        self.reward = reward
        self.lane_keeping_reward = lane_keeping_reward
        self.substeps = as_count("substeps", substeps)
        self.action_names = tuple(name for name, _, _ in table)
        self._speed_changes = np.array([ds for _, ds, _ in table], dtype=np.int64)
        self._lane_changes = np.array([dl for _, _, dl in table], dtype=np.int64)
        self._params = params
        self._keep_params = keep_params
        # whether each action's lane change takes effect from each target lane (`apply_action`),
        # derived once: the lane-keeping family's bookkeeping reads it at every expansion
        n_lanes = controller.lanes.kinds.shape[0]
        self._moves_lane = np.array(
            [
                [apply_action(controller, 0, lane, 0, int(dl))[1] != lane for dl in self._lane_changes]
                for lane in range(n_lanes)
            ],
            dtype=bool,
        )
        params_type: type = type(params)  # mypy infers type[Any], which it does not treat as Hashable
        self._kernel = _expand_kernel(params_type)
        self._fallback = _fallback_kernel(params_type)
        self._all_actions = np.arange(len(table))
        # the actions of each held code of the lane-keeping family (`fallback_values`): -1 (the
        # prefix, any lane-keeping action) or a speed change + 1 held after it; and the others
        families = {
            code: (self._lane_changes == 0) & ((self._speed_changes + 1 == code) | (code == -1))
            for code in (-1, 0, 1, 2)
        }
        self._hold_families = [(code, np.flatnonzero(family)) for code, family in families.items()]
        self._other_actions = {code: np.flatnonzero(~family) for code, family in families.items()}
        # `fallback_values` memo: each state's continuations (key: its id; the entry holds the
        # state, so the id names it while the entry lives), and the last expansion (whose
        # children the next `fallback_values` call is likely asked for)
        self._continuations: dict[int, tuple] = {}
        self._last_expansion: tuple[BicycleState, np.ndarray, list[BicycleState]] | None = None
        self._no_parent = (
            np.zeros((len(table), RECORDED_DECISIONS)),
            np.full(len(table), -1, dtype=np.int64),
            np.zeros(len(table), dtype=np.int8),
        )
        self._index_cache: tuple[Any, np.ndarray] | None = None
        self._scratch = np.empty(8)  # one box [-x | x] for the reward (the kernels allocate nothing)

    @property
    def n_actions(self) -> int:
        """The number of actions."""
        return len(self.action_names)

    @property
    def actions(self) -> tuple[int, ...]:
        """The planner's actions: the indices ``0 .. n_actions - 1``."""
        return tuple(range(self.n_actions))

    def with_reward(self, reward: Any, *, lane_keeping_reward: Any = None) -> BicycleModel:
        """The same ego with another reward (e.g. the next decision's obstacle table).

        Parameters
        ----------
        reward : CompiledBoxReward
            The new reward (as for the constructor).
        lane_keeping_reward : CompiledBoxReward, optional
            The new reward of paths that keep their lane (as for the constructor).

        Returns
        -------
        BicycleModel
        """
        actions = list(zip(self.action_names, self._speed_changes.tolist(), self._lane_changes.tolist()))
        return BicycleModel(
            self.controller, reward, actions, substeps=self.substeps, lane_keeping_reward=lane_keeping_reward
        )

    def _kept_after(self, state: BicycleState, index: np.ndarray) -> list[tuple[int, int]]:
        """``(keep_depth, keep_hold)`` of each action's child (`BicycleState`): is the path still of the family?"""
        lost = (-1, -1)
        if state.keep_depth < 0:
            return [lost] * index.shape[0]
        out = []
        moves = self._moves_lane[state.lane]
        for a in index.tolist():
            if moves[a]:  # the lane change takes effect
                out.append(lost)
                continue
            # an action whose lane change has no effect moves the ego as its speed change alone
            code = int(self._speed_changes[a]) + 1
            if state.keep_depth < LANE_KEEPING_PREFIX:
                out.append((state.keep_depth + 1, -1))
            elif state.keep_hold in (-1, code):
                out.append((state.keep_depth + 1, code))
            else:
                out.append(lost)
        return out

    def _action_index(self, actions) -> np.ndarray:
        cache = self._index_cache
        if cache is not None and cache[0] is actions:
            return cache[1]
        try:
            index = [int(a) for a in actions]
        except (TypeError, ValueError):
            raise InputError(f"actions must be action indices (integers), got {actions!r}") from None
        if any(i != a for i, a in zip(index, actions)) or any(not 0 <= i < self.n_actions for i in index):
            raise InputError(f"actions must be action indices in [0, {self.n_actions}), got {list(actions)!r}")
        value = np.array(index, dtype=np.int64)
        if isinstance(actions, tuple):
            self._index_cache = (actions, value)
        return value

    def expand(self, state: BicycleState, actions) -> tuple[list, np.ndarray, np.ndarray]:
        """Step every action from ``state`` over the decision's sub-steps, in one compiled call.

        Parameters
        ----------
        state : BicycleState
            The current state (`initial_state` or an earlier transition).
        actions : sequence of int
            Action indices in ``[0, n_actions)``.

        Returns
        -------
        next_states : list of BicycleState
        rewards : ndarray, shape (len(actions),)
            The minimum reward over the sub-step states, in [0, 1].
        terminals : ndarray of bool, shape (len(actions),)
        """
        if type(state) is not BicycleState:
            check_instance("state", state, BicycleState, "a BicycleState (see BicycleModel.initial_state)")
        index = self._action_index(actions)
        n = index.shape[0]
        out_x = np.empty((n, 4))
        meta = np.empty((n, 2), dtype=np.int64)
        rewards = np.empty(n)
        terminals = np.empty(n, dtype=bool)
        after = self._kept_after(state, index)
        kept = [depth >= 0 for depth, _ in after]
        if self._keep_params is None or not any(kept):
            self._run_expand(self._params, state, index, out_x, meta, rewards, terminals)
        elif all(kept):
            self._run_expand(self._keep_params, state, index, out_x, meta, rewards, terminals)
        else:
            mask = np.array(kept)
            for params, rows in ((self._keep_params, mask), (self._params, ~mask)):
                part = np.flatnonzero(rows)
                o_x, o_m = np.empty((part.shape[0], 4)), np.empty((part.shape[0], 2), dtype=np.int64)
                o_r, o_t = np.empty(part.shape[0]), np.empty(part.shape[0], dtype=bool)
                self._run_expand(params, state, index[part], o_x, o_m, o_r, o_t)
                out_x[part], meta[part], rewards[part], terminals[part] = o_x, o_m, o_r, o_t
        out_x.setflags(write=False)
        time = state.time + self.substeps
        levels, lanes = meta[:, 0].tolist(), meta[:, 1].tolist()
        children = [BicycleState(out_x[i], levels[i], lanes[i], time, *after[i]) for i in range(n)]
        self._last_expansion = (state, index, children)
        return children, rewards, terminals

    def _run_expand(self, params, state: BicycleState, index, out_x, meta, rewards, terminals) -> None:
        self._kernel(
            self.controller,
            params,
            state.x,
            state.level,
            state.lane,
            state.time,
            self._speed_changes[index],
            self._lane_changes[index],
            self.substeps,
            self._scratch,
            out_x,
            meta,
            rewards,
            terminals,
        )

    def step(self, state: BicycleState, action) -> tuple[BicycleState, float, bool]:
        """One transition ``(next_state, reward, terminal)`` (see `expand`).

        Parameters
        ----------
        state : BicycleState
            The current state.
        action : int
            An action index.
        """
        next_states, rewards, terminals = self.expand(state, (action,))
        return next_states[0], float(rewards[0]), bool(terminals[0])

    def fallback_values(self, states: Sequence[BicycleState], gamma: float) -> np.ndarray:
        """Continuation bounds (`FallbackModel`): the best return of holding one action from each state.

        For each state and each action a, the transitions of `expand` are repeated with
        a held (braking with SLOWER, keeping the speed with IDLE, ...) until the first
        terminal one (a possible collision, leaving the road, or the end of the
        reward's obstacle table, where the reward is 0); the value is the largest of
        the discounted returns ``sum_k gamma^k r_k`` over the actions. Each is the
        exact return of one fixed plan from the state (the ego is a point), so the
        largest is a lower bound of the robust value there.

        Parameters
        ----------
        states : sequence of BicycleState
            The states (the children of a tree node).
        gamma : float
            The discount factor, in (0, 1).

        Returns
        -------
        numpy.ndarray, shape (len(states),)
            In ``[0, 1 / (1 - gamma)]``.

        Notes
        -----
        The model remembers each state's continuations (up to `MEMO_STATES` states). When
        ``states`` are the children of the last `expand`, as in the search, the child
        reached by action a does not roll a out again: holding a from it is the parent's
        continuation of a after its first decision, the same states and rewards, so the
        value is the same to the last bit (a fifth of the rollouts at five actions).
        """
        if type(gamma) is not float or not 0.0 < gamma < 1.0:
            gamma = as_discount("gamma", gamma)
        n = len(states)
        xs = np.empty((n, 4))
        for i, state in enumerate(states):
            if type(state) is not BicycleState:
                check_instance(f"states[{i}]", state, BicycleState, "a BicycleState (see BicycleModel.initial_state)")
            if state.keep_hold not in _KEEP_HOLDS:
                raise InputError(f"states[{i}].keep_hold must be -1, 0, 1 or 2, got {state.keep_hold!r}")
            if np.shape(state.x) != (4,):
                raise DimensionError(f"states[{i}].x must have shape (4,), got shape {np.shape(state.x)}")
            xs[i] = state.x
        levels = np.array([state.level for state in states], dtype=np.int64)
        lanes = np.array([state.lane for state in states], dtype=np.int64)
        times = np.array([state.time for state in states], dtype=np.int64)
        n_actions = self.n_actions
        record = np.empty((n, n_actions, RECORDED_DECISIONS))
        recorded = np.empty((n, n_actions), dtype=np.int64)
        tables = np.full((n, n_actions), _REWARD_TABLE, dtype=np.int8)
        out = np.zeros(n)
        if self._keep_params is None or not any(state.kept for state in states):
            # every continuation reads the table for any ego
            groups = [(self._params, np.arange(n), self._all_actions)]
        else:
            # a path of the family that holds an action of the family stays in it: the lane-keeping
            # table; any other continuation (a lane change, or another action than the one already
            # held) is bounded on the table for any ego. A lane change without effect is bounded
            # there too; the maximum is the same as `step`'s, since such an action moves the ego
            # exactly as the speed action of its family, which is held on the lane-keeping table
            hold = np.array([state.keep_hold if state.kept else -2 for state in states])
            groups = [(self._params, np.flatnonzero(hold == -2), self._all_actions)]
            for code, family in self._hold_families:
                rows = np.flatnonzero(hold == code)
                tables[np.ix_(rows, family)] = _LANE_KEEPING_TABLE
                groups += [(self._keep_params, rows, family), (self._params, rows, self._other_actions[code])]
        arrived_by, parent = self._arrivals(states)
        for params, rows, columns in groups:
            if rows.shape[0] == 0 or columns.shape[0] == 0:
                continue
            self._fallback(
                self.controller,
                params,
                xs,
                levels,
                lanes,
                times,
                rows,
                columns,
                self._speed_changes,
                self._lane_changes,
                self.substeps,
                gamma,
                self._scratch,
                arrived_by,
                *parent,
                tables,
                record,
                recorded,
                out,
            )
        memo = self._continuations
        if len(memo) + n > MEMO_STATES:
            memo.clear()
        for i, state in enumerate(states):
            memo[id(state)] = (state, record, recorded, tables, i)
        return out

    def _arrivals(self, states: Sequence[BicycleState]):
        """The action that led to each of ``states`` from their parent, and the parent's continuations.

        Known when ``states`` are the children of the last `expand` (by identity) and the
        expanded state's continuations were kept by an earlier `fallback_values`: then
        ``(index, (record, recorded, tables))`` of the parent's row, else -1 everywhere
        (`_fallback_kernel`'s ``arrived_by`` and ``parent_*``).
        """
        if self._last_expansion is None:
            return np.full(len(states), -1, dtype=np.int64), self._no_parent
        parent, index, children = self._last_expansion
        entry = self._continuations.get(id(parent))
        if (
            entry is None
            or entry[0] is not parent
            or len(children) != len(states)
            or any(state is not child for state, child in zip(states, children))
        ):
            return np.full(len(states), -1, dtype=np.int64), self._no_parent
        _, record, recorded, tables, row = entry
        return index, (record[row], recorded[row], tables[row])

    def predict(self, state: BicycleState, action) -> tuple[np.ndarray, np.ndarray, BicycleState]:
        """The sub-step states and controls of one action: what the world's ego does under them.

        Parameters
        ----------
        state : BicycleState
            The current state.
        action : int
            An action index.

        Returns
        -------
        states : ndarray, shape (substeps, 4)
            The ego after each sub-step (the runtime check's predicted points).
        controls : ndarray, shape (substeps, 2)
            ``(acceleration, steering)`` at each sub-step (admissible for `RoadWorld`).
        next_state : BicycleState
            The state after the decision (as `expand` returns it).
        """
        (a,) = self._action_index((action,))
        level, lane = apply_action(
            self.controller, state.level, state.lane, int(self._speed_changes[a]), int(self._lane_changes[a])
        )
        states = np.empty((self.substeps, 4))
        controls = np.empty((self.substeps, 2))
        x0 = np.ascontiguousarray(state.x, dtype=float)
        lane = bicycle_kernels.ego_rollout(self.controller, x0, level, lane, self.substeps, states, controls)
        final = states[-1].copy()
        final.setflags(write=False)
        (after,) = self._kept_after(state, np.array([a]))
        return states, controls, BicycleState(final, int(level), int(lane), state.time + self.substeps, *after)

    def first_possible_collision(self, state: BicycleState, plan: Sequence[int], horizon: int) -> int:
        """The first sub-step at which a plan's ego may collide, or ``horizon + 1`` if none does.

        The plan's actions are taken in turn from ``state`` and its last one is then held;
        each sub-step state is scored with the reward its transition reads in `expand`
        (``lane_keeping_reward`` while the path is of the lane-keeping family). A
        possible collision is a zero case of that reward: the ego's rectangle meets an
        obstacle box, or leaves the road.

        Parameters
        ----------
        state : BicycleState
            The start state.
        plan : sequence of int
            Action indices, at least one.
        horizon : int
            Sub-steps examined, ``>= 1`` (at most to the end of the rewards' obstacle
            tables, beyond which every state is a zero case).

        Returns
        -------
        int
            In ``[1, horizon + 1]``, relative to ``state.time``.
        """
        horizon = as_count("horizon", horizon)
        actions = [int(a) for a in self._action_index(tuple(plan))]
        if not actions:
            raise InputError("plan must hold at least one action, got an empty sequence")
        elapsed = 0
        decision = 0
        while elapsed < horizon:
            action = actions[min(decision, len(actions) - 1)]
            states, _, after = self.predict(state, action)
            reward = self.lane_keeping_reward if after.kept and self.lane_keeping_reward is not None else self.reward
            times = state.time + 1 + np.arange(states.shape[0])
            _, collided = reward.box_minimum(states, states, times)
            collided = np.asarray(collided, dtype=bool)[: horizon - elapsed]
            if collided.any():
                return elapsed + 1 + int(np.argmax(collided))
            elapsed += states.shape[0]
            decision += 1
            state = after
        return horizon + 1

    def initial_state(self, x, *, level: int, lane: int, time: int = 0) -> BicycleState:
        """The planner's root state from the ego's (exactly known) state.

        Parameters
        ----------
        x : array_like, shape (4,)
            ``(x, y, v, psi)``.
        level : int
            The current speed level, in ``[0, len(target_speeds))``.
        lane : int
            The current target lane, a lane index.
        time : int
            The absolute sub-step index (the reward's time).

        Returns
        -------
        BicycleState

        Raises
        ------
        DimensionError, NonFiniteError, InputError
            On a malformed state, level, lane or time.
        """
        x = as_finite_array("x", x, (4,)).copy()
        x.setflags(write=False)
        level = as_count("level", level, minimum=0)
        if level >= self.controller.target_speeds.shape[0]:
            raise InputError(f"level must be < {self.controller.target_speeds.shape[0]}, got {level}")
        lane = as_count("lane", lane, minimum=0)
        if lane >= self.controller.lanes.kinds.shape[0]:
            raise InputError(f"lane must be a lane index < {self.controller.lanes.kinds.shape[0]}, got {lane}")
        return BicycleState(x, level, lane, as_count("time", time, minimum=0))
