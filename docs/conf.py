"""Sphinx configuration of the nrsfm documentation site (``sphinx-build -W docs OUT``)."""

import nrsfm

project = "nrsfm"
author = "the nrsfm authors"
copyright = "2026, the nrsfm authors"
release = version = nrsfm.__version__

extensions = [
    "myst_parser",  # the pages and the rendered lessons are Markdown
    "numpydoc",  # the docstrings are numpydoc
    "sphinx.ext.autosummary",  # one API page per public name
    "sphinx.ext.mathjax",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "**/*_files"]
templates_path = ["_templates"]

myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
suppress_warnings = ["myst.xref_missing"]  # links into folders and CSV files

autosummary_generate = True
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

html_theme = "pydata_sphinx_theme"
html_title = "nrsfm"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_show_sourcelink = False
