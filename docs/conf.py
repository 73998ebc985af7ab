"""Sphinx configuration of the flexshell documentation: the Markdown guides of docs/ (MyST), the API
reference generated from the docstrings (autodoc + autosummary over the packages ``shell`` and
``dynamics``), the example gallery (docs/gallery/) and the tutorial.

    python3 -m pip install -e ".[docs]"
    python3 -m sphinx -W -b html docs docs/_build/html       (warnings are errors, as in the test)
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

project = "flexshell"
author = "the flexshell developers"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon",
              "sphinx.ext.mathjax"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}  # autosummary writes .rst stubs
root_doc = "index"
exclude_patterns = ["_build", "api/_autosummary/**/.*"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = False
napoleon_numpy_docstring = True
html_theme = "alabaster"
html_static_path = []
