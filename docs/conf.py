"""Sphinx configuration of the vcnc-gym documentation site (``make docs``).

Markdown pages through myst-parser, the furo theme (Gymnasium's), the API
reference from the numpydoc docstrings (autodoc + napoleon, numpy style).
The env and controller pages are generated at build time from
``vcnc_gym.envs.registry.SUITE`` and ``vcnc_baselines.registry`` by
``_ext/vcnc_pages.py``; the numpydoc types are shown as text by
``_ext/plain_types.py``, and a reference to a re-exported or inherited name
links to where it is documented (``_ext/canonical_refs.py``).  No network: no intersphinx.  Nothing is filtered:
``make docs`` fails on any warning, the docstrings' markup included.
"""

from __future__ import annotations

import os
import sys
import warnings

sys.path.insert(0, os.path.abspath("_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import vcnc_gym  # noqa: E402

# The pages document every version of every id on purpose: Gymnasium's note that an older version is out of date
# (printed by gym.make) says nothing to the reader of the build's output.
warnings.filterwarnings("ignore", message=".*is out of date.*", category=DeprecationWarning)

project = "vcnc-gym"
author = "the vcnc-gym authors"
copyright = "2026, the vcnc-gym authors"
release = vcnc_gym.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "vcnc_pages",
    "plain_types",
    "canonical_refs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "README.md"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

# numpydoc docstrings, read by napoleon
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# members defined in each module only (a package's __all__ re-exports are documented where they are defined)
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
# what autodoc need not import to document the modules (none of these is needed to build the docs)
autodoc_mock_imports: list[str] = []

html_theme = "furo"
html_title = f"vcnc-gym {release}"
html_static_path: list[str] = []
