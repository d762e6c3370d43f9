"""Benchmarks behind ``comems4build bench <target>``: each module prints figures (no timed tests)."""
