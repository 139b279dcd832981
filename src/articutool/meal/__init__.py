"""The feeding task in the physics world: the simulated arm the feeding tree commands
(``sim_arm``), a bite and a meal run in the world (``bites``), their progress display and the
``articutool meal`` command. It joins the feeding task, which does not know the simulator, to
the simulator."""
