"""Feeding: the action library (strategies as data) and, to come, the behaviour tree that runs
a bite and a meal (issue 10)."""
