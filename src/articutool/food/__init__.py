"""The food on the utensil as physics the planner can evaluate: the dish's geometry, the
hydrostatics of a liquid in it and (``slosh``) the first sloshing mode. Pure NumPy on the
spec's numbers; importable by the verifier and the physics world alike."""
