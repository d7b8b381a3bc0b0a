"""Sphinx configuration of the seactl documentation (build: see README, "Documentation")."""

import seactl

project = "seactl"
author = "seactl developers"
release = version = seactl.__version__
copyright = "seactl developers, MIT licence"

extensions = [
    "myst_nb",                  # Markdown pages and tutorials executed at build time
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",                 # renders the numpydoc sections the tests validate
    "sphinx.ext.mathjax",
    "sphinx_copybutton",
]

source_suffix = {".md": "myst-nb", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "**/.ipynb_checkpoints"]
root_doc = "index"

# --- tutorials: executed on every build, any error fails the build
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 600
nb_execution_show_tb = True
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# --- API reference
autosummary_generate = False
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()   # validated by tests/test_docstrings.py

# --- HTML
html_theme = "pydata_sphinx_theme"
html_title = "seactl"
html_static_path = ["_static"]
html_css_files = ["seactl.css"]
html_theme_options = {
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_sidebars = {"index": []}
html_show_sourcelink = False
