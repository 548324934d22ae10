"""Experiments of the paper and beyond: many seeded trials per algorithm, on any executor.

- :mod:`~ceamcl.experiments.executors`: where trials run (serial, local processes, Dask).
- :mod:`~ceamcl.experiments.routes`: courses (built in, or a route file beside a ROS map).
- :mod:`~ceamcl.experiments.trials`: one seeded trial and what it records.
- :mod:`~ceamcl.experiments.metrics`: converged/expired time, success and the rest.
- :mod:`~ceamcl.experiments.table1`, :mod:`~ceamcl.experiments.delta`,
  :mod:`~ceamcl.experiments.marked`, :mod:`~ceamcl.experiments.kidnapped`: the experiments.
- :mod:`~ceamcl.experiments.evaluate_log`: ``ceamcl evaluate-log``, global localisation from
  many start points of a real log (:mod:`~ceamcl.experiments.log_windows` picks the windows,
  :mod:`~ceamcl.experiments.log_report` writes its tables and figures;
  :mod:`~ceamcl.experiments.tracking_log` is its ``--tracking`` mode;
  :mod:`ceamcl.io.truth_check` says how well a log's truth explains its scans).
- :mod:`~ceamcl.experiments.figures`: their figures, apart from measurement.

Algorithms are looked up by name in :mod:`ceamcl.filters.registry`; replaying one log
(``ceamcl run``) is :mod:`ceamcl.replay`, not an experiment.

Definitions and the protocol: ``docs/experiments.md``.
"""
