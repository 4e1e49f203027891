"""minimaxplan.scenarios."""
