"""minimaxplan.kernels: box primitives and the compiled-reward protocol (numpy and numba only).

The layer below `minimaxplan.planners` and `minimaxplan.scenarios` that both use, so
that neither imports the other:

* `minimaxplan.kernels.box_primitives`: `maximum`, `minimum` (NaN-propagating, as
  numpy's) and `box_gap_sq`, the one box-disc gap of the project (the collision test
  of a box of positions against a disc, or against a moving disc's predicted box);
* `minimaxplan.kernels.reward_protocol`: how a reward family's exact box minimum
  (Theorem 1) is written once, as a compiled kernel on one box, and reaches the
  planners' compiled engine (`box_reward_minimum`, `register_reward_params`,
  `has_compiled_minimum`) and numpy callers (`box_minima`); the cache keys of the
  kernels that call it (`sources_digest`, `minimum_sources`, `compile_per_params_type`); the `BoxReward`,
  `UncheckedBoxReward`, `StateIndexedReward` and `CompiledBoxReward` protocols a planner model reads.

* `minimaxplan.kernels.bicycle`: the kinematic bicycle and the driving ego's
  controllers, compiled once for the world and the planner (`LaneGeometry`,
  `EgoController`, `ego_control`);
* `minimaxplan.kernels.driving_reward`: the driving reward's compiled box minimum
  (`DrivingParams`);
* `minimaxplan.kernels.vertex_bounds`: the traffic forecast's interval arithmetic on 2 x 2
  matrix families (`interval_matvec`, `vertex_bound`, `contraction_vertex_factor`);
* `minimaxplan.kernels.lateral_bounds`: its bounds of the bicycle's nonlinear terms over
  boxes (the lateral remainder, the footprint boxes, the contraction bound's vertex box,
  the corner norms of a metric).

A user's reward family gets an exact box minimum and a compiled kernel by exposing a
registered ``kernel_params`` namedtuple and an overload of `box_reward_minimum`; see
`minimaxplan.kernels.reward_protocol` and ``docs/rewards.md``.
"""

from .bicycle import EgoController, LaneGeometry, ego_control
from .box_primitives import box_gap_sq, box_gaps_sq, maximum, minimum
from .driving_reward import DrivingParams
from .reward_protocol import (
    BoxReward,
    CompiledBoxReward,
    StateIndexedReward,
    UncheckedBoxReward,
    box_minima,
    box_minima_kernel,
    box_reward_minimum,
    compile_per_params_type,
    has_compiled_minimum,
    minimum_sources,
    register_reward_params,
    sources_digest,
)

__all__ = [
    "BoxReward",
    "DrivingParams",
    "EgoController",
    "LaneGeometry",
    "ego_control",
    "CompiledBoxReward",
    "StateIndexedReward",
    "UncheckedBoxReward",
    "box_gap_sq",
    "box_gaps_sq",
    "box_minima",
    "box_minima_kernel",
    "box_reward_minimum",
    "compile_per_params_type",
    "has_compiled_minimum",
    "maximum",
    "minimum",
    "minimum_sources",
    "register_reward_params",
    "sources_digest",
]
