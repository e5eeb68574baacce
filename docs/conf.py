"""Sphinx configuration of the rov-mav manual (`make docs`; tests/test_docs.py builds it with -W -n).

Why these tools: Sphinx with MyST keeps every page plain Markdown that GitHub renders as well; sphinx-argparse
writes the command reference from the CLI's own argparse parsers (rov_mav.cli.build_parser), so an option renamed in
the code is renamed in the manual; furo is a clean theme with a working search; sphinx-mathjax-offline ships MathJax
with the site, so the equations render with no network. The file-format tables come from the pydantic validation
models by the small extension in _ext/rovmav_docs.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))      # the rov_mav package of this checkout
sys.path.insert(0, str(HERE / "_ext"))

project = "rov-mav"
author = "the rov-mav authors"
copyright = "the rov-mav authors, MIT licence"

extensions = [
    "myst_parser",
    "sphinxarg.ext",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",
    "rovmav_docs",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "bench/**", "report/table.md", "Thumbs.db", ".DS_Store"]

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

html_theme = "furo"
html_title = "rov-mav"
html_static_path: list[str] = []
html_show_sourcelink = False

nitpicky = True
suppress_warnings: list[str] = []
smartquotes = False
