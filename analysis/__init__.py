"""minimaxplan.analysis."""
