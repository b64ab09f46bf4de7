"""Learning: models, losses, training, evaluation, prediction, the VAE and the delta study.

Run by workflow/rules/models.smk and vae.smk.
"""
