"""Labels: PMF/CDF math, the configuration grid and splits, the merged dataset, convergence (workflow/rules/datasets.smk)."""
