"""Learning: models, losses, training, evaluation, prediction, the VAE and the delta study (workflow/rules/models.smk, vae.smk)."""
