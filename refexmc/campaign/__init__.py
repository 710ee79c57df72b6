"""Sampling and seeding, execution, Parquet storage and manifest."""
