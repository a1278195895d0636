"""The settings schema both front ends share: each setting declared once (:mod:`app.settings.schema`).

From it: the ``qsid`` options (:mod:`app.settings.cli`), the strict check of a value by type
(:mod:`app.settings.check`, for the panel and settings files) and the ``qsid sweep`` line
(:mod:`app.settings.command`). Importing this package loads no numerics.
"""

from .schema import BY_NAME, SETTINGS, E, Setting, cli_default, engine, resolve, value_default

__all__ = ["BY_NAME", "E", "SETTINGS", "Setting", "cli_default", "engine", "resolve", "value_default"]
