"""drltg's performance comparisons: ``python -m benchmarks [suite ...] [--device cpu|cuda] [--quick]``."""
