"""Sphinx configuration of the rivercal documentation (``make docs`` builds it into docs/_build/html).

Everything the pages need ships with the build (theme, MathJax, figures): the site opens without a
network connection. The tutorial is executed at every build (sphinx-gallery), the API reference is
written from the packages' ``__all__`` (``_ext/rivercal_docs.py``), the CLI reference from the typer app
and the file formats from their JSON Schemas.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import rivercal  # noqa: E402

project = "rivercal"
author = "rivercal developers"
copyright = "rivercal developers, MIT licence"
version = release = rivercal.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 copied into the build: no CDN
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "rivercal_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# sphinx-gallery's sources (tutorials/, verification/) and the by-products it writes beside its pages
exclude_patterns = ["_build", "tutorials", "verification", "tools", "explanation/optimisers-twin.md",
                    "**.ipynb_checkpoints"] + [
    f"{gallery}/*.{ext}" for gallery in ("tutorial", "explanation/verification")
    for ext in ("ipynb", "py", "zip", "md5", "json")]
templates_path: list[str] = []
nitpicky = False
suppress_warnings = ["myst.header"]  # the Markdown pages of the repository start some sections at level 3

# -- autodoc and numpydoc --------------------------------------------------------------------------------
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"show-inheritance": True}
autodoc_mock_imports: list[str] = []
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- MyST (the Markdown pages) ---------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# -- the tutorial and the verification figures, executed at every build ---------------------------------
sphinx_gallery_conf = {
    "examples_dirs": ["tutorials", "verification"],
    "gallery_dirs": ["tutorial", "explanation/verification"],
    "filename_pattern": r".*\.py",  # execute every script: a tutorial that is not run could rot
    "run_stale_examples": True,  # run the tutorial at every build, even when its text did not change
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "capture_repr": ("_repr_html_", "__repr__"),
    "download_all_examples": False,
    "write_computation_times": False,  # its page loads DataTables from a CDN
    "show_signature": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
    "min_reported_time": 3600,
}

# -- HTML ------------------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"rivercal {release}"
html_static_path = ["_static"]
html_css_files = ["rivercal.css"]
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "navbar_align": "left",
    "header_links_before_dropdown": 6,
    "footer_start": ["copyright"],
    "footer_end": [],
    "secondary_sidebar_items": ["page-toc"],
}
html_context = {"default_mode": "light"}
