"""The feeding task in the physics world: a bite and a meal run in the world (``bites``), the
feeding tree commanding the PC's arm over the world's arm driver
(:func:`articutool.sim.arm_driver.sim_arm`), their progress display and the
``articutool meal`` command. It joins the feeding task, which does not know the simulator, to
the simulator."""
