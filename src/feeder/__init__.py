"""feeder: predict how extruded parts leave a linear conveyor feeder with passive fences.

One module per stage of the study: ``parts`` / ``geometry`` (the part library), ``features`` (DFT
shape features), ``sim`` (pybullet drops), ``labels`` (PMF/CDF maths), ``datasets`` (splits and
scalers), ``models`` / ``train`` / ``evaluate`` (regression models), ``vae`` / ``delta`` (the VAE
and the delta-to-full model), ``report`` (tables and figures). The ``feeder`` command line
(``feeder.cli``) is how the Snakemake workflow calls each stage.
"""

__version__ = "0.1.0"
