"""Simulation: fences, the scene, drops of a part through a fence configuration (workflow/rules/simulate.smk)."""
