"""The 3-D web viewer (``articutool view``): scene, plans, verification and recorded runs.

``recording`` (the :class:`~articutool.viewer.recording.Recorder` any physics-world run can
attach, and the file format), ``plan`` (pure: what a plan looks like), ``geometry`` (meshes
from the feeding world's model), ``app`` (the viser page), ``export`` (video without a
browser), ``cli``.
"""
