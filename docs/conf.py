"""Sphinx configuration of the starsense manual (``make docs``)."""

from importlib.metadata import version as _version

project = "starsense"
author = "the starsense developers"
copyright = "the starsense developers"  # noqa: A001 (Sphinx's own name)
release = _version("starsense")
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
templates_path = ["_templates"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# The API reference: every name `import starsense` exports, from its numpydoc docstring.
autosummary_generate = True
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
# Validation of the exported names' docstrings: every parameter documented (PR01) and no
# undocumented one listed (PR02), types and descriptions given (PR04, PR07), a Returns section
# where the function returns (RT01), a one-line summary (SS01, SS06 excepted: long summaries
# are allowed). A failed check is a warning, and `make docs` turns warnings into errors.
numpydoc_validation_checks = {"PR01", "PR02", "PR04", "PR07", "RT01", "SS01", "GL08"}


html_theme = "pydata_sphinx_theme"
html_title = "starsense"
html_static_path = ["_static"]
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
