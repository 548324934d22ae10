"""``ceamcl bench``: speed of the sensor kernels, the filters and CEAMCL, beside Nav2 AMCL.

:func:`~ceamcl.bench.suite.run_bench` measures, :func:`~ceamcl.bench.report.write_report`
writes ``bench.json`` and ``bench.md``. docs/performance.md explains the figures.
"""

from ceamcl.bench.report import write_report
from ceamcl.bench.suite import BenchSettings, run_bench

__all__ = ["BenchSettings", "run_bench", "write_report"]
