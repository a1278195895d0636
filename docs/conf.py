"""Sphinx configuration of the qsid docs: the API reference from the docstrings, the CLI from the parsers,
every shown output from running it (``docs/qsidext.py``).

Build (warnings are errors): ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the checkout's packages, not an older installed copy
sys.path.insert(0, str(ROOT / "docs"))  # cliparsers (the CLI parsers for sphinx-argparse), qsidext

import qsid_core  # noqa: E402

project = "qsid"
author = "the qsid authors"
copyright = "the qsid authors"
release = version = qsid_core.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # the docstrings are numpydoc style
    "sphinx.ext.mathjax",
    "sphinxarg.ext",  # the CLI reference, rendered from the argparse parsers themselves
    "qsidext",  # qsid-run, qsid-python, the dashboard's tables: generated at build time
    "runblock",  # qsid-exec / qsid-cli: code and commands run while the docs build, their real output shown
]

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_param = False  # "shape (n, m)" is text, not a cross-reference to every attribute named n
napoleon_use_ivar = True  # a dataclass's "Attributes" section as fields, not a second copy of its members
# each object once, where it is defined (modules re-export through __all__)
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_inherit_docstrings = False  # the standard library's docstrings are not ours to render
autodoc_typehints = "description"

# "shape (n, m)" in a field's type makes Sphinx look for an object named n; several dataclasses
# have such a field, so the (harmless, unlinked) lookup is ambiguous
suppress_warnings = ["ref.python"]

exclude_patterns = ["_build", "data", "_generated"]
smartquotes = False  # u'Ru, 'dare' and "..." are shown as the programs print them
html_theme = "alabaster"
html_static_path: list[str] = []
