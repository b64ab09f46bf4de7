"""Parts: the library, outlines and meshes, DFT shape features (workflow/rules/parts.smk)."""
