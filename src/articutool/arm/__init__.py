"""Arm models: the Jaco 2 and the Jaco + Articutool, built with Pinocchio; scene and collision with coal."""
