"""Random uncertain systems, controllers and true-trajectory simulation for the planner tests,
and the straight three-lane road of the road baselines' tests."""

import numpy as np

from minimaxplan.models import Box, UncertainLinearSystem
from minimaxplan.models.sets import hypercube_signs
from minimaxplan.planners.controllers import LinearFeedback, OpenLoop


def random_system(rng, p=None, q=None, d=None):
    """A random plant, Metzler or not, discretised from continuous time with a random dt."""
    p = int(rng.integers(2, 5)) if p is None else p
    q = int(rng.integers(1, 3)) if q is None else q
    d = int(rng.integers(1, 3)) if d is None else d
    r = int(rng.integers(1, p + 1))
    dt = float(rng.uniform(0.02, 0.4))
    A = rng.normal(size=(p, p)) / np.sqrt(p)
    phi = rng.normal(size=(d, p, p)) * (rng.random((d, p, p)) < 0.5) / p
    B = rng.normal(size=(p, q))
    D = rng.normal(size=(p, r))
    w_half = rng.uniform(0.0, 0.3, r)
    theta_lo = rng.uniform(-0.5, 0.3, d)
    theta = Box(theta_lo, theta_lo + rng.uniform(0.0, 0.6, d))
    system = UncertainLinearSystem.from_continuous(A, phi, B, D=D, w=Box(-w_half, w_half), theta=theta, dt=dt)
    return system


def random_controllers(rng, system, n=None, saturate=None):
    """OpenLoop and LinearFeedback controllers, some with saturation limits that will activate."""
    p, q = system.nstates, system.ninputs
    n = int(rng.integers(2, 4)) if n is None else n
    controllers = []
    for _ in range(n):
        if rng.random() < 0.4:
            controllers.append(OpenLoop(rng.uniform(-1, 1, q)))
        else:
            limited = rng.random() < 0.6 if saturate is None else saturate
            limit = float(rng.uniform(0.05, 1.0))
            controllers.append(
                LinearFeedback(
                    rng.normal(size=(q, p)),
                    rng.uniform(-2, 2, p),
                    rng.uniform(-0.5, 0.5, q),
                    u_low=-limit if limited else None,
                    u_high=limit if limited else None,
                )
            )
    return controllers


def parameter_samples(rng, box: Box, n_random=4):
    """Every vertex of the parameter box plus random interior points, shape (k, d)."""
    return np.vstack([box.vertices(), rng.uniform(box.low, box.high, (n_random, box.dim))])


def initial_samples(rng, lower, upper, n):
    """n states of the box: corners first (extremes), then random points."""
    corners = lower + (hypercube_signs(len(lower)) + 1) / 2 * (upper - lower)
    points = rng.uniform(lower, upper, (n, len(lower)))
    k = min(n, len(corners))
    points[:k] = corners[rng.permutation(len(corners))[:k]]
    return points


def disturbance(rng, w: Box, n):
    """Disturbances of n realisations: mostly box vertices (extremes), some interior."""
    signs = rng.choice([-1.0, 1.0], size=(n, w.dim))
    w_values = w.center + signs * w.radius
    interior = rng.random(n) < 0.25
    w_values[interior] = rng.uniform(w.low, w.high, (int(interior.sum()), w.dim))
    return w_values


def simulate(rng, system, thetas, x0, controllers, substeps):
    """True trajectories for each (theta, x0) pair along a controller sequence.

    Returns states of shape (n, len(controllers) * substeps + 1, p).
    """
    A = system.A(thetas)  # (n, p, p)
    x = np.array(x0, dtype=float)
    states = [x]
    for controller in controllers:
        for _ in range(substeps):
            u = controller.control(x)
            w = disturbance(rng, system.w, x.shape[0])
            x = np.einsum("nij,nj->ni", A, x) + u @ system.B.T + w @ system.D.T
            states.append(x)
    return np.stack(states, axis=1)


def inside(states, lower, upper, tol=1e-9):
    slack = tol * (1.0 + np.abs(states))
    return bool(np.all(states >= lower - slack) and np.all(states <= upper + slack))


def run_baseline_episode(planner, start, goal, centers, radii, theta, seed):
    """A baseline in closed loop in a real world whose layout is replaced by the given one."""
    from minimaxplan.planners.dwa import NavigationScene
    from minimaxplan.scenarios.geometry import CircularObstacles
    from minimaxplan.scenarios.worlds import make_world

    world = make_world("static", seed)
    world.start, world.goal = np.asarray(start, float), np.asarray(goal, float)
    world.obstacles = CircularObstacles(np.asarray(centers, float).reshape(-1, 2), np.asarray(radii, float))
    world.true_theta = np.asarray(theta, float)
    world.state = np.concatenate([world.start, np.zeros(2)])
    scene = NavigationScene(world.goal, world.obstacles.centers, world.obstacles.radii)
    if hasattr(planner, "reset"):
        planner.reset()
    path = [world.state[:2].copy()]
    while not world.done:
        world.apply_held(planner.plan(world.measure(), scene))
        path.append(world.state[:2].copy())
    return world, np.array(path)


def robot_system(dt=0.1):
    """The paper's robot (double integrator with anisotropic friction), friction prior [0.2, 0.8]^2."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    phi = np.zeros((2, 4, 4))
    phi[0, 2, 2] = phi[1, 3, 3] = -1.0
    B = np.zeros((4, 2))
    B[2, 0] = B[3, 1] = 1.0
    return UncertainLinearSystem.from_continuous(
        A, phi, B, D=B.copy(), w=Box([-0.1, -0.1], [0.1, 0.1]), theta=Box([0.2, 0.2], [0.8, 0.8]), dt=dt
    )


ROBOT_ACTIONS = [OpenLoop(u) for u in ([-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0])]


def three_lanes(points):
    """A straight 3-lane road along +x, lanes centred at y = 0, 4, 8 (the highway's frame):
    a `RoadReference` (progress, offset from the nearest lane centre, heading 0)."""
    p = np.asarray(points, dtype=float)
    nearest = np.clip(np.round(p[..., 1] / 4.0), 0, 2)
    return p[..., 0], p[..., 1] - 4.0 * nearest, np.zeros(p.shape[:-1])


def on_three_lanes(points):
    """Whether points lie on `three_lanes` (|y - 4| <= 6): a `RoadTest`."""
    return np.abs(np.asarray(points, dtype=float)[..., 1] - 4.0) <= 6.0
