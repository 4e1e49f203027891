"""Theorem 1 through the interval-model adapter: the surrogate is a lower bound of what is collected.

Which comparison is the right one. The interval model's reward for a decision is
``r_n = min_{s=1..S} min_{x in box_{n,s}} J(x, t_{n,s})``: the worst reward over the
sub-step boxes between decisions n and n+1. The matching true quantity for one
realisation (theta, w, x0, pedestrians) is ``min_s J(x_{n,s}, t_{n,s})`` along the true
trajectory under the same action sequence: the robust objective (10) at decision
resolution with the same per-decision aggregate. Theorem 1's proof (Appendix A) is term
by term: ``x_{n,s}`` lies in ``box_{n,s}`` (inclusion), so the true worst sub-step reward
is at least ``r_n``, and the discounted sums compare the same way. A true collision
ends the episode (rewards 0 afterwards); it implies that the box collided too, so the
surrogate is terminal no later. We assert the inequality for the min aggregate (the
strong form) and for the per-decision mean of the sub-step rewards (which is >= the
min, so it must hold too; a sum over sub-steps would be S times the mean and compares
with S times the surrogate).

The plan is the planner's `Decision.sequence`; its surrogate value is the robust lower
bound `Decision.lower` (checked), so the test says: the guaranteed value that the
planner reports is never more than what any admissible realisation collects.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimaxplan.models import Box
from minimaxplan.planners import RobustTreePlanner
from minimaxplan.planners.interval_model import IntervalModel
from minimaxplan.scenarios.geometry import CircularObstacles, MovingObstacles
from minimaxplan.scenarios.rewards import GoalReward

from . import _systems as systems

seeds = st.integers(0, 2**31 - 1)
TOL = 1e-9


def surrogate_return(model, root, sequence, gamma):
    """Discounted surrogate along a sequence; rewards after the first terminal transition are 0."""
    _, _, rewards, terminals = model.rollout(root, sequence)
    total, alive = 0.0, True
    for n, (r, term) in enumerate(zip(rewards, terminals)):
        if not alive:
            break
        total += gamma**n * r
        alive = not term
    return total, rewards, terminals


def true_pedestrian_paths(rng, moving: MovingObstacles, n_steps):
    """Positions at sub-steps time0 .. time0 + n_steps, velocities at the extremes of their boxes."""
    paths = [np.array(moving.positions)]
    for _ in range(n_steps):
        signs = rng.choice([-1.0, 1.0], size=moving.positions.shape)
        velocity = moving.velocities + signs * moving.velocity_uncertainty
        paths.append(paths[-1] + velocity * moving.dt)
    return np.stack(paths)  # (n_steps + 1, m, 2)


def true_returns(reward, states, t0, substeps, gamma, pedestrians):
    """Per realisation: discounted sums of the per-decision min and mean of the true rewards.

    states (R, n*S + 1, p); pedestrians (R, n*S + 1, m, 2) or None. Returns (min_return,
    mean_return, per_decision_min (R, n)).
    """
    R, steps, _ = states.shape
    n_decisions = (steps - 1) // substeps
    values = np.empty((R, steps - 1))
    collided = np.zeros((R, steps - 1), dtype=bool)
    for i in range(R):
        for j in range(1, steps):
            moving = None if pedestrians is None else pedestrians[i, j]
            v, c = reward.evaluate(states[i, j], t0 + j, moving_positions=moving)
            values[i, j - 1], collided[i, j - 1] = v, c
    # after a true collision the episode is over: every later sub-step reward is 0
    ended = np.cumsum(collided, axis=1) > 0
    values = np.where(ended, 0.0, values)
    per_decision = values.reshape(R, n_decisions, substeps)
    discount = gamma ** np.arange(n_decisions)
    minimum = per_decision.min(axis=2)
    return minimum @ discount, per_decision.mean(axis=2) @ discount, minimum


def random_scene(rng, with_moving, t0):
    goal = rng.uniform(-4, 4, 2)
    n = int(rng.integers(0, 6))
    obstacles = CircularObstacles(rng.uniform(-3, 3, (n, 2)), rng.uniform(0.1, 0.8, n))
    moving = None
    if with_moving:
        m = int(rng.integers(1, 3))
        moving = MovingObstacles(
            rng.uniform(-3, 3, (m, 2)),
            rng.uniform(-1.5, 1.5, (m, 2)),
            rng.uniform(0.2, 0.4, m),
            velocity_uncertainty=float(rng.uniform(0.0, 0.3)),
            dt=float(rng.uniform(0.05, 0.2)),
            time0=t0,
        )
    return GoalReward(goal, obstacles=obstacles, moving_obstacles=moving, robot_radius=float(rng.uniform(0, 0.4)))


def check_theorem1(rng, planner, models, truth_index, reward, root, substeps, gamma, engine="compiled"):
    decision = planner.plan(root)
    assert planner.engine_used == engine  # both engines are exercised (they build the same tree)
    sequence = decision.sequence
    surrogate = [surrogate_return(m, root, sequence, gamma) for m in models]
    # the plan's surrogate value is the reported robust lower bound
    assert min(s[0] for s in surrogate) == pytest.approx(decision.lower, abs=1e-12)
    model = models[truth_index]
    value, rewards, terminals = surrogate[truth_index]
    system = model.system
    parameters = model.parameters
    thetas = systems.parameter_samples(rng, parameters, n_random=3)
    x0 = systems.initial_samples(rng, np.asarray(root.lower), np.asarray(root.upper), len(thetas))
    controllers = [model.controllers[a] for a in sequence]
    n_steps = len(sequence) * substeps
    for _ in range(2):
        states = systems.simulate(rng, system, thetas, x0, controllers, substeps)
        pedestrians = None
        moving = reward.moving_obstacles
        if len(moving):
            pedestrians = np.stack([true_pedestrian_paths(rng, moving, n_steps) for _ in range(len(thetas))])
        by_min, by_mean, per_decision = true_returns(reward, states, root.time, substeps, gamma, pedestrians)
        assert np.all(by_min >= decision.lower - TOL)
        assert np.all(by_mean >= by_min - TOL)
        # term by term, up to the surrogate's first terminal transition
        alive = np.concatenate([[True], ~np.cumsum(terminals)[:-1].astype(bool)])
        assert np.all(per_decision[:, alive] >= rewards[alive] - TOL)
    return decision


@settings(max_examples=40)
@given(seeds, st.integers(1, 3), st.booleans())
def test_collected_return_is_never_below_the_plans_surrogate(seed, substeps, with_moving):
    rng = np.random.default_rng(seed)
    system = systems.random_system(rng)
    controllers = systems.random_controllers(rng, system)
    t0 = int(rng.integers(0, 10))
    reward = random_scene(rng, with_moving, t0)
    gamma = float(rng.uniform(0.5, 0.95))
    # a parameter set inside the prior: the guarantee is over this set
    lo = rng.uniform(system.theta.low, system.theta.high)
    parameters = Box(lo, rng.uniform(lo, system.theta.high))
    model = IntervalModel(system, parameters, reward, controllers, substeps=substeps)
    planner = RobustTreePlanner([model], model.actions, gamma=gamma, budget=int(rng.integers(3, 15)))
    lo0 = rng.uniform(-1, 1, system.nstates)
    root = model.initial_state(lo0, lo0 + rng.uniform(0, 0.3, system.nstates), time=t0)
    check_theorem1(rng, planner, [model], 0, reward, root, substeps, gamma)


@settings(max_examples=25)
@given(seeds, st.integers(1, 3))
def test_multi_model_guarantee_holds_for_the_true_hypothesis(seed, substeps):
    """With several hypotheses, the reported lower bound holds for whichever one is true."""
    rng = np.random.default_rng(seed)
    p, q = int(rng.integers(2, 5)), int(rng.integers(1, 3))
    hypotheses = [systems.random_system(rng, p=p, q=q) for _ in range(int(rng.integers(2, 4)))]
    controllers = systems.random_controllers(rng, hypotheses[0])
    reward = random_scene(rng, bool(rng.integers(0, 2)), 0)
    models = [IntervalModel(h, h.theta, reward, controllers, substeps=substeps) for h in hypotheses]
    gamma = 0.9
    planner = RobustTreePlanner(models, models[0].actions, gamma=gamma, budget=10)
    lo0 = rng.uniform(-1, 1, p)
    root = models[0].initial_state(lo0, lo0 + rng.uniform(0, 0.2, p))
    # separate (not linked) models: the Python engine
    check_theorem1(rng, planner, models, int(rng.integers(0, len(models))), reward, root, substeps, gamma, "python")


def test_robot_example_is_not_vacuous():
    """A robot among obstacles: the guarantee is positive and the true return exceeds it."""
    rng = np.random.default_rng(11)
    system = systems.robot_system()
    controllers = systems.ROBOT_ACTIONS
    obstacles = CircularObstacles([[1.5, 1.0], [0.5, 2.0], [2.5, 2.5]], [0.4, 0.3, 0.5])
    moving = MovingObstacles([[3.0, 0.0]], [[-0.5, 0.5]], [0.3], velocity_uncertainty=0.2, dt=0.1)
    reward = GoalReward([4.0, 4.0], obstacles=obstacles, moving_obstacles=moving, robot_radius=0.3)
    model = IntervalModel(system, Box([0.4, 0.3], [0.6, 0.5]), reward, controllers, substeps=5)
    planner = RobustTreePlanner([model], model.actions, gamma=0.9, budget=40)
    root = model.initial_state([0.0, 0.0, 0.0, 0.0], [0.05, 0.05, 0.0, 0.0])
    decision = check_theorem1(rng, planner, [model], 0, reward, root, 5, 0.9)
    assert decision.lower > 0.3 and len(decision.sequence) >= 3
