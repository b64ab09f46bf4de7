"""Labels: PMF/CDF math, the configuration grid and splits, the merged dataset, convergence.

Run by workflow/rules/datasets.smk.
"""
