"""Sphinx configuration of the seactl documentation (build: see README, "Documentation")."""

import os
from pathlib import Path

import seactl

HERE = Path(__file__).resolve().parent
# One figure style for the tutorials' kernels (they inherit this environment) and the
# examples (sphinx-gallery resets matplotlib to it before each script).
os.environ["MATPLOTLIBRC"] = str(HERE / "matplotlibrc")

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
    "sphinx_gallery.gen_gallery",   # the examples: scripts executed at build time
]

source_suffix = {".md": "myst-nb", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "**/.ipynb_checkpoints", "gallery/*.ipynb", "gallery/*.py",
                    "gallery/*.zip", "gallery/*.json", "gallery/*.md5"]
root_doc = "index"

# --- tutorials: executed on every build, any error fails the build
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 600
nb_execution_show_tb = True
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# --- examples: examples/gallery/*.py, each run once per build (its figures and output shown)
def _matplotlib_style(gallery_conf, fname):
    import matplotlib

    matplotlib.rc_file_defaults()
    matplotlib.rc_file(str(HERE / "matplotlibrc"))


sphinx_gallery_conf = {
    "examples_dirs": "../examples/gallery",
    "gallery_dirs": "gallery",
    "filename_pattern": r".*\.py$",        # execute every example
    "reset_modules": (_matplotlib_style,),
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "show_memory": False,
    "capture_repr": (),                  # output is what the script prints, no reprs
    "abort_on_example_error": True,
}
# The style function above makes the configuration unpicklable: Sphinx then rebuilds every
# page, which the forced execution of the tutorials does anyway.
suppress_warnings = ["config.cache"]

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
