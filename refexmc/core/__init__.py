"""Numba-jitted physics and flight software on plain arrays in SI units.

Nothing here imports config, pandas, pyarrow or click; inputs are validated before they get here.
"""
