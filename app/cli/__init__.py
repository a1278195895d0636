"""The ``qsid`` command line: list systems, sweep the word length, reproduce the letter's figures.

::

    qsid systems [--json]
    qsid sweep   [--system NAME|FILE] [--bits SPEC] [...] [--json] [--out FILE]
    qsid reproduce --system dc-motor|boeing747 --out DIR [...]

Modules: :mod:`~app.cli.main` (entry point, errors), :mod:`~app.cli.parser`
(options, defaults from the engine), :mod:`~app.cli.runner` (config, executor,
progress), :mod:`~app.cli.output` (JSON, table), and one module per command
(:mod:`~app.cli.systems`, :mod:`~app.cli.sweep`, :mod:`~app.cli.reproduce`).
All numerics are the engine's (:mod:`qsid_core`).
"""

from .main import build_parser, main

__all__ = ["main", "build_parser"]
