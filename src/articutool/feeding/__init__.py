"""Feeding: the action library (strategies as data) and the behaviour tree that runs a bite and
a meal."""
