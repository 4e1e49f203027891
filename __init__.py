"""minimaxplan: robust motion planning under model uncertainty, with checked guarantees.

Subpackages: `minimaxplan.models`, `minimaxplan.verify`, `minimaxplan.planners`,
`minimaxplan.scenarios`, `minimaxplan.analysis`.
"""

__version__ = "0.1.0"
