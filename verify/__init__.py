"""minimaxplan.verify."""
