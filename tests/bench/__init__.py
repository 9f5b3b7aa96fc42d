"""Benchmark harness: rosgate (or any rosbridge server) against a bare-tornado ceiling."""
