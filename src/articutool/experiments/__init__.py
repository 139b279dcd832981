"""The thesis' physical experiments (Exp. 1, 2b, 2c, 3; Ch. 5–6) in the physics world:
statistics, trial protocols, a resumable runner, figures and one report."""
