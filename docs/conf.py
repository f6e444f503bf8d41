"""Sphinx configuration of pillar-xval's documentation (``make docs``)."""

import os
import sys
from importlib import metadata

# The packages are importable from the installed (editable) toolkit; the repository root is
# added for a build from a plain checkout.
sys.path.insert(0, os.path.abspath(".."))
sys.path.insert(0, os.path.abspath("_ext"))

project = "pillar-xval"
author = "the pillar-xval developers"
copyright = "2026, the pillar-xval developers"
try:
    release = metadata.version("pillar-xval")
except metadata.PackageNotFoundError:  # a checkout that was never installed
    release = "0+unknown"
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinxarg.ext",
    "myst_parser",
    "matplotlib.sphinxext.plot_directive",
    "pillar_docs",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_tables"]
myst_heading_anchors = 3

# API reference: one page per public module, from the docstrings (numpydoc).
autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

# numpydoc turns a References section into citations [1], [2]; the docstrings name their
# sources in the prose ("Kalker's minimum principle") rather than by a [1]_ mark, so an
# unmarked citation is the intended form, not a dangling one.
# Docstrings name sibling modules relative to their package (:mod:`.contact` in
# fem_reference.axisym), which Sphinx looks up in every package; where two packages have a
# module of that name it warns and links the first.  ref.python is that warning alone.
suppress_warnings = ["ref.citation", "ref.python"]

# Tutorials' figures are drawn by their own code at build time, so an example cannot rot.
plot_include_source = True
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 90)]

# The planner's examples plan with the cost fits' own seconds: the same pages on every
# machine, and no calibration of the build machine.
os.environ.setdefault("PILLAR_XVAL_MACHINE", "reference")

html_theme = "alabaster"
html_title = f"pillar-xval {release}"
