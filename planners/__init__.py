"""minimaxplan.planners."""
