"""The 3-D web viewer (``articutool view``): scene, plans, verification and recorded runs.

It reads the run recordings of :mod:`articutool.sim.recording` (the recorder lives beside the
world it records). ``plan`` (pure: what a plan looks like), ``geometry`` (meshes
from the feeding world's model), ``app`` (the viser page), ``export`` (video without a
browser), ``cli``.
"""
