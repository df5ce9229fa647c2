"""Sphinx configuration of pinstab's documentation (docs/README in index.md: how to build it, and why Sphinx).

The build fetches nothing: no intersphinx inventories, no theme assets from the network; MathJax is loaded by the
reader's browser from its CDN when a page with mathematics is opened (the build itself does not download it).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # pinstab itself comes from the installed (editable) package
os.environ.setdefault("MPLBACKEND", "Agg")

project = "pinstab"
author = "the pinstab developers"
copyright = "pinstab developers, BSD-3-Clause"

from pinstab import __version__ as release  # noqa: E402

version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "sg_execution_times.rst", "auto_examples/*.ipynb", "auto_examples/*.zip"]

# MyST: $...$ and $$...$$ mathematics, amsmath environments, heading anchors for [text](#anchor) links
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

# autodoc + napoleon: Google-style docstrings with units in brackets ([m], [rad/s])
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # Attributes: as fields (properties of the same name are documented by autodoc)

# sphinx-gallery: the demos/ scripts, rendered with their code; executed: the two that only print (the others
# write files and are run, with their figures asserted, by tests/test_demos.py)
sphinx_gallery_conf = {
    "examples_dirs": [str(ROOT / "demos")],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"(compare_methods|user_constraint)\.py$",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_signature": False,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "image_scrapers": (),
}

html_theme = "furo"
html_title = f"pinstab {release}"
html_static_path: list[str] = []
html_show_sourcelink = True
# nothing fetched at build time: no intersphinx, no external images
intersphinx_mapping: dict = {}
suppress_warnings: list[str] = []


# Links from a page to a Markdown file of the repository outside docs/ (benchmarks/README.md, results tables) work
# on GitHub as they are; in the site MyST would take them for pages it does not have. They become download links to
# the file itself, as MyST makes of every other file (JSON results, CSV tables).
def _outside_markdown_as_downloads(app, doctree) -> None:
    from docutils import nodes
    from sphinx import addnodes

    env = app.env
    srcdir = Path(env.srcdir).resolve()
    here = (srcdir / env.docname).parent
    for node in list(doctree.findall(addnodes.pending_xref)):
        if node.get("refdomain") != "doc" or node.get("reftype") != "myst":
            continue
        target = str(node["reftarget"])
        if target in env.found_docs:
            continue
        path = Path(target + ".md")
        path = path if path.is_absolute() else srcdir / path
        if not path.is_file() or srcdir in path.resolve().parents:
            continue
        download = addnodes.download_reference(
            refdomain=None, reftarget=os.path.relpath(path, here), refdoc=env.docname, reftype="myst", refexplicit=True
        )
        download += node.children or [nodes.literal(text=path.name)]
        node.replace_self(download)


def setup(app) -> None:
    app.connect("doctree-read", _outside_markdown_as_downloads, priority=100)
