"""The qsid version: the one place it is written (the tests check it equals pyproject.toml's)."""

__version__ = "0.1.0"
