"""Simulation: transports executed against the simulated wrist and its onboard loop."""
