"""The first run: the planner says what it compiles, and where it caches it, before compiling.

A fresh checkout compiles the numba kernels on its first plan (tens of seconds, see
benchmarks/bench_cold_start.py). Nothing below `analysis` prints: the kernels' factories
log on the "minimaxplan.kernels" logger, and the CLI shows those records on stderr.
These tests check the order (message first, then numba's compile) with a logging handler
and a numba compile-event listener; none of them is timed.
"""

import logging
from collections import namedtuple

import numba.core.config
import numpy as np
import pytest
from numba.core import event

from minimaxplan.kernels import compile_per_params_type, reward_protocol
from minimaxplan.planners import compiled_search
from minimaxplan.planners.box_kernels import stack_rewards_kernel
from minimaxplan.scenarios.compiled_rewards import GoalParams

ColdProbeParams = namedtuple("ColdProbeParams", ["scale"])


class _Recorder(logging.Handler, event.Listener):
    """One ordered log of both the logger's records and numba's compile events."""

    def __init__(self):
        logging.Handler.__init__(self, level=logging.DEBUG)
        self.entries: list[tuple[str, str]] = []

    def emit(self, record):
        self.entries.append(("log", record.levelname + " " + record.getMessage()))

    def on_start(self, ev):
        self.entries.append(("compile", ev.data["dispatcher"].py_func.__qualname__))

    def on_end(self, ev):
        pass


@pytest.fixture
def recorder():
    logger = logging.getLogger("minimaxplan.kernels")
    handler = _Recorder()
    previous = logger.level
    logger.setLevel(logging.DEBUG)
    logger.addHandler(handler)
    event.register("numba:compile", handler)
    try:
        yield handler
    finally:
        event.unregister("numba:compile", handler)
        logger.removeHandler(handler)
        logger.setLevel(previous)


@pytest.fixture
def empty_cache(monkeypatch, tmp_path):
    """numba's disk cache seen as empty (the stub of a fresh checkout): no index for any kernel."""
    monkeypatch.setattr(reward_protocol, "_cache_index", lambda dispatcher: (tmp_path / "absent.nbi", str(tmp_path)))
    return tmp_path


def test_the_message_comes_before_the_compile(recorder, monkeypatch, tmp_path):
    # a really empty disk cache: numba places a new dispatcher's cache under NUMBA_CACHE_DIR
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(tmp_path))

    def probe(params, x):
        return params.scale * x

    kernel = compile_per_params_type(probe, ColdProbeParams, what="the probe kernel")
    assert kernel(ColdProbeParams(2.0), 3.0) == 6.0
    kinds = [kind for kind, _ in recorder.entries]
    assert "compile" in kinds, "the probe kernel was compiled"
    first_log, first_compile = kinds.index("log"), kinds.index("compile")
    assert first_log < first_compile
    message = recorder.entries[first_log][1]
    assert message.startswith("INFO compiling the probe kernel for ColdProbeParams")
    assert str(tmp_path) in message
    assert list(tmp_path.rglob("*.nbi")), "numba cached the probe kernel where the message said"


def test_the_search_kernel_announces_itself_before_any_call(recorder, empty_cache):
    # a fresh dispatcher (not the process-wide cached one) and no call: nothing compiles
    kernel = compiled_search.search_kernel.__wrapped__(GoalParams)
    assert not kernel.signatures
    assert [kind for kind, _ in recorder.entries] == ["log"]
    message = recorder.entries[0][1]
    assert message.startswith("INFO compiling the planner's search kernel") and "GoalParams" in message
    assert f"cached in {empty_cache}" in message


def test_the_reward_kernel_announces_itself(recorder, empty_cache):
    stack_rewards_kernel.__wrapped__(GoalParams)
    assert len(recorder.entries) == 1
    assert recorder.entries[0][1].startswith(
        "INFO compiling the interval model's pessimistic-reward kernel for GoalParams"
    )


def test_a_cached_kernel_is_only_a_debug_record(recorder, monkeypatch, tmp_path):
    index = tmp_path / "present.nbi"
    index.write_bytes(b"")
    monkeypatch.setattr(reward_protocol, "_cache_index", lambda dispatcher: (index, str(tmp_path)))
    compiled_search.search_kernel.__wrapped__(GoalParams)
    assert len(recorder.entries) == 1
    assert recorder.entries[0][1].startswith("DEBUG loading the planner's search kernel (")


def test_the_cache_index_is_where_numba_writes_it():
    def located(params, x):
        return params.scale + x

    kernel = compile_per_params_type(located, ColdProbeParams)
    index, directory = reward_protocol._cache_index(kernel)
    assert index is not None and index.suffix == ".nbi"
    assert index.name.startswith("test_cold_start.") and ".located_" in index.name
    kernel(ColdProbeParams(1.0), np.float64(2.0))
    assert index.exists() and directory == str(index.parent)


def test_cached_kernels_close_over_plain_digests_only():
    """numba keys a cached closure by its cells' pickles: a dispatcher's differs in every process.

    The search kernel closed over `tree_ops.reset`, `select` and `expand`, so a new process
    never found it in the disk cache and recompiled it (seconds on every run); a cell
    holding only the int digest keys the same entry in every process.
    """
    from minimaxplan.kernels import box_minima_kernel
    from minimaxplan.planners import box_kernels
    from minimaxplan.scenarios.compiled_rewards import SpeedLaneParams

    kernels = [box_kernels.substep, box_kernels.propagate]
    for params_type in (GoalParams, SpeedLaneParams):
        kernels += [
            compiled_search.search_kernel(params_type),
            stack_rewards_kernel(params_type),
            box_minima_kernel(params_type),
        ]
    for kernel in kernels:
        cells = [cell.cell_contents for cell in kernel.py_func.__closure__ or ()]
        assert cells and all(type(value) is int for value in cells), (kernel.py_func.__qualname__, cells)


# Run in a fresh process with an empty cache: the robot's first plan (the benchmark's), listening to
# numba's compile events; prints one JSON line: {qualified name: [signature, ...]} of what compiled.
FIRST_PLAN = r"""
import json
from collections import defaultdict

import numpy as np
from numba.core import event

compiled = defaultdict(list)


class Listener(event.Listener):
    def on_start(self, ev):
        dispatcher = ev.data["dispatcher"]
        compiled[dispatcher.py_func.__module__ + ":" + dispatcher.py_func.__qualname__].append(str(ev.data["args"]))

    def on_end(self, ev):
        pass


event.register("numba:compile", Listener())

from minimaxplan.analysis.episode import LoopConfig
from minimaxplan.analysis.robot_methods import velocity_controllers
from minimaxplan.analysis.robot_scenario import RobotScenario
from minimaxplan.planners.comparison import multi_model_robust_planner, root_state

scenario, config = RobotScenario("pedestrian"), LoopConfig()
world = scenario.make_world(0, config)
pairs = [(h.system, h.system.theta) for h in scenario.hypotheses(world)]
planner = multi_model_robust_planner(
    pairs, scenario.objective(world, world.goal, uncertain=True), velocity_controllers(config),
    gamma=config.gamma, budget=config.budget, substeps=world.params.substeps,
)
start = np.asarray(world.state, dtype=float)
planner.plan(root_state(planner, start - 0.01, start + 0.01, time=0))
assert planner.engine_used == "compiled", planner.engine_used
first = dict(compiled)
compiled.clear()
from minimaxplan.scenarios import SpeedLaneReward

further = multi_model_robust_planner(
    pairs, SpeedLaneReward(target_speed=1.0, speed_range=2.0, speed_indices=(2, 3), lateral_index=1,
                           lane_width=1.0, n_lanes=3, lane_weight=0.5, speed_weight=0.5,
                           obstacles=world.obstacles, robot_radius=world.params.robot_radius),
    velocity_controllers(config), gamma=config.gamma, budget=config.budget, substeps=world.params.substeps,
)
further.plan(root_state(further, start - 0.01, start + 0.01, time=0))
assert further.engine_used == "compiled", further.engine_used
print(json.dumps({"first": first, "further": compiled}))
"""


@pytest.fixture(scope="module")
def plans_compile(tmp_path_factory):
    """What the robot's first plan, then a plan with a further reward family, compile in a fresh process."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path_factory.mktemp("numba-cache")))
    done = subprocess.run([sys.executable, "-c", FIRST_PLAN], env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def first_plan_compiles(plans_compile):
    """What the robot's first plan compiles in a fresh process with an empty numba cache."""
    return plans_compile["first"]


def test_the_first_plan_compiles_every_function_once(first_plan_compiles):
    """One signature per function: no literal, layout or readonly specialisation compiles a kernel twice.

    (A bool literal passed to the box code once compiled it three times, one per
    combination of its two flags.)
    """
    ours = {name: signatures for name, signatures in first_plan_compiles.items() if name.startswith("minimaxplan.")}
    assert "minimaxplan.planners.box_kernels:_step" in ours
    assert any(name.startswith("minimaxplan.planners.compiled_search:search_kernel.") for name in ours)
    twice = {name: signatures for name, signatures in ours.items() if len(signatures) != 1}
    assert not twice


def test_the_first_plan_compiles_the_box_code_once_and_no_python_entry_point(first_plan_compiles):
    """The compiled search calls the box code itself, not the Python-facing kernels.

    `propagate` and `substep` are the numpy-facing forms (the Python engine,
    `IntervalModel.expand`); the tree's Python entry points (`start`,
    `expand_and_select`) belong to the Python engine. The compiled engine's first plan
    compiled `propagate` and `substep` too, each with a copy of the box code inlined by
    numba (most of the 23 s the first plan took).
    """
    names = set(first_plan_compiles)
    for entry in (
        "minimaxplan.planners.box_kernels:_make_propagate.<locals>.propagate",
        "minimaxplan.planners.box_kernels:_make_substep.<locals>.substep",
        "minimaxplan.planners.tree_ops:start",
        "minimaxplan.planners.tree_ops:expand_and_select",
    ):
        assert entry not in names
    assert [name for name in names if name.endswith(":_step")] == ["minimaxplan.planners.box_kernels:_step"]


def test_the_first_plan_compiles_no_single_call_helper_and_not_the_decision_walk(first_plan_compiles):
    """Each compiled function is a library that every compiled caller above it optimises and emits again.

    The tree operations with one call site are inlined by numba into it (`reset`,
    `add_children`, `backup`, the heap's push and pop), and so is the reward loop
    `pessimistic_rewards`; the path comparison is part of `_before`, and `best_path`
    (a walk of the tree's depth) is Python: none of them compiles on its own (each did,
    on the code before this test).
    """
    names = set(first_plan_compiles)
    for helper in ("reset", "add_children", "backup", "_heap_push", "_heap_pop", "_path_before", "best_path"):
        assert f"minimaxplan.planners.tree_ops:{helper}" not in names
    for kept in ("select", "expand", "_before"):
        assert f"minimaxplan.planners.tree_ops:{kept}" in names
    # the reward loop too, into the search kernel (it is compiled per reward family anyway)
    assert "minimaxplan.planners.box_kernels:pessimistic_rewards" not in names


def test_the_kernels_have_no_c_wrapper():
    """No compiled function builds numba's C wrapper (for first-class function values, unused here)."""
    from minimaxplan.kernels import box_minima_kernel
    from minimaxplan.planners import box_kernels, tree_ops

    dispatchers = [
        compiled_search.search_kernel(GoalParams),
        stack_rewards_kernel(GoalParams),
        box_minima_kernel(GoalParams),
        box_kernels.substep,
        box_kernels.propagate,
        box_kernels.pessimistic_rewards,
        box_kernels._step,
        tree_ops.start,
        tree_ops.expand_and_select,
        tree_ops.select,
        tree_ops.expand,
        tree_ops._before,
    ]
    for dispatcher in dispatchers:
        assert dispatcher.targetoptions.get("no_cfunc_wrapper") is True, dispatcher.py_func.__qualname__
    assert box_kernels.pessimistic_rewards.targetoptions.get("no_cpython_wrapper") is True
    assert box_kernels.pessimistic_rewards.targetoptions.get("inline") == "always"


def test_best_path_walks_the_children_of_largest_lower_bound():
    from minimaxplan.planners import tree_ops

    tree = tree_ops.allocate(7, 1, 3, 0.9, tree_ops.discount_table(0.9, 4))
    tree.first_child[:7] = [1, -1, 4, -1, -1, -1, -1]
    tree.lower[:7] = [0.0, 0.5, 0.7, 0.7, 0.2, 0.3, 0.3]  # ties: the first child
    tree.counts[tree_ops.MAX_DEPTH] = 2
    path = tree_ops.best_path(tree)
    assert path.dtype == np.int64 and path.tolist() == [1, 1]
    tree.first_child[0] = -1
    assert tree_ops.best_path(tree).tolist() == []


# Run in a fresh process: what importing the robot's side of the library loads.
LAZY_IMPORTS = r"""
import json, sys
import minimaxplan.verify.selection
from minimaxplan.scenarios import GoalReward, make_world, robot_hypotheses
loaded = {"cvxpy": "cvxpy" in sys.modules,
          "road": sorted(name for name in sys.modules if name.split(".")[-1] in
                         ("road", "road_world", "traffic_models", "vehicles", "driving_reward")
                         and name.startswith("minimaxplan.scenarios"))}
from minimaxplan.verify import check_assumption4
from minimaxplan.scenarios import DrivingReward
loaded["cvxpy_when_asked"] = "cvxpy" in sys.modules
loaded["driving_when_asked"] = "minimaxplan.scenarios.driving_reward" in sys.modules
print(json.dumps(loaded))
"""


def test_the_robot_side_imports_neither_cvxpy_nor_the_road_worlds():
    """`minimaxplan.verify` and `minimaxplan.scenarios` import each name's module when it is first asked for.

    The LP model elimination (`verify.selection`) imported `lmi`, hence cvxpy and
    scipy.stats (0.9 s of a fresh process); the robot's rewards and worlds imported the
    road worlds, the traffic and the driving reward.
    """
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", LAZY_IMPORTS], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    loaded = json.loads(done.stdout.strip().splitlines()[-1])
    assert loaded == {"cvxpy": False, "road": [], "cvxpy_when_asked": True, "driving_when_asked": True}


@pytest.mark.parametrize("package", ["minimaxplan.verify", "minimaxplan.scenarios"])
def test_every_lazy_name_resolves_and_is_listed(package):
    import importlib

    module = importlib.import_module(package)
    for name in module.__all__:
        if name in ("RobotNavigationEnv", "RoadDrivingEnv"):
            continue  # the optional `gym` extra (tests/scenarios/test_gym_env.py)
        value = getattr(module, name)
        assert getattr(value, "__name__", name) == name or not callable(value), (package, name)
        assert name in dir(module)
    assert not hasattr(module, "not_a_name")


def test_a_further_family_compiles_only_its_own_kernels_once(plans_compile):
    """A second reward family compiles its box minimum, the reward loop and the search kernel, each once.

    The box code, the tree operations and the primitives come from the first plan's
    libraries. (The lane term's ``math.floor`` is an int64 in numba, which compiled a
    second `maximum`, for (int64, float64).)
    """
    further = plans_compile["further"]
    ours = {name: signatures for name, signatures in further.items() if name.startswith("minimaxplan.")}
    assert not {name: signatures for name, signatures in ours.items() if len(signatures) != 1}
    assert "minimaxplan.kernels.box_primitives:maximum" not in ours
    assert any(name.startswith("minimaxplan.planners.compiled_search:search_kernel.") for name in ours)
    assert "minimaxplan.planners.box_kernels:pessimistic_rewards" not in ours  # inlined into the search kernel
    assert any(name.startswith("minimaxplan.scenarios.compiled_rewards:_speed_lane_box_minimum") for name in ours)
    assert not [name for name in ours if name.startswith("minimaxplan.planners.tree_ops:") or name.endswith(":_step")]
