"""refexmc: fast, reproducible Monte-Carlo campaigns for thruster-controlled attitude control."""

__version__ = "0.1.0"
