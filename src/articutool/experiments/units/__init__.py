"""The experiments, one module each (:class:`articutool.experiments.unit.Experiment`;
every module here with an ``EXPERIMENT`` is registered)."""
