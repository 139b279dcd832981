"""The Articutool onboard software: kinematics, filter, controller, primitives, runtime, drivers."""
