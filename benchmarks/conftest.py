"""pytest-benchmark regression benchmarks; see benchmarks/test_kernels.py."""
