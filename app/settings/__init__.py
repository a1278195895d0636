"""The settings both front ends share, and everything that carries them: each setting declared once
(:mod:`app.settings.schema`).

From it: the ``qsid`` options (:mod:`app.settings.cli`), the strict check of a value by type
(:mod:`app.settings.check`, for the panel and settings files) and the ``qsid sweep`` line
(:mod:`app.settings.command`); the values a front end holds (:mod:`app.settings.values`, typed text read by
:mod:`app.settings.typed`), their engine configuration for either kind of plant (:mod:`app.settings.config`),
settings files (:mod:`app.settings.files`) and view codes (:mod:`app.settings.viewcodes`). Importing this
package loads no numerics (its submodules ``values``, ``config``, ``files`` and ``viewcodes`` do).
"""

from .schema import BY_NAME, SETTINGS, E, Setting, cli_default, engine, resolve, value_default

__all__ = ["BY_NAME", "E", "SETTINGS", "Setting", "cli_default", "engine", "resolve", "value_default"]
