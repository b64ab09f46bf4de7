"""Benchmarks: accuracy against time, yaw designs, jams, cost, scheduling (workflow/rules/bench.smk)."""
