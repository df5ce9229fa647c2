"""Benchmarks: work-precision sweeps with peers, per-step overhead, scaling (issue 5)."""
