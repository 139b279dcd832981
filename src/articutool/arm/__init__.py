"""Arm models: the Jaco 2 + Articutool built with Pinocchio (``model``); the scene and its
collision geometry with coal (``scene``); inverse kinematics (``ik``)."""
