"""Benchmarks: commands that print JSON and write plots (never timed asserts in tests)."""
