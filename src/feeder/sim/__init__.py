"""Simulation: the scene's bodies, drops of a part through a fence configuration and the adaptive
initial-yaw design (workflow/rules/simulate.smk). The fences themselves are :mod:`feeder.lane`."""
