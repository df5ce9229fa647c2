"""The documentation site builds with warnings as errors, offline, and its pages hold what they promise.

``sphinx-build -W --keep-going -b html docs OUT``: MyST pages, the API reference from the docstrings (a malformed
docstring is a warning, so an error here), the command-line reference from ``build_parser()`` and the examples
gallery, which runs ``demos/compare_methods.py`` and ``demos/user_constraint.py`` (a failing example fails the
build). The other demos are run, their figures asserted, by ``tests/test_demos.py``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytest.importorskip("sphinx", reason="the docs extra (pip install -e '.[docs]') builds the site")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, MPLBACKEND="Agg")
    # no proxy: a build that tried to fetch anything (an intersphinx inventory, a theme asset) fails instead of
    # waiting; sphinx-build itself is the venv's
    for name in ("http_proxy", "https_proxy", "HTTP_PROXY", "HTTPS_PROXY"):
        env[name] = "http://127.0.0.1:9"
    completed = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-E", "-b", "html", str(DOCS), str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert completed.returncode == 0, f"sphinx-build failed:\n{completed.stderr[-6000:]}\n{completed.stdout[-2000:]}"
    return out


def test_every_page_is_built(site: Path):
    sources = [p.relative_to(DOCS).with_suffix(".html") for p in DOCS.rglob("*.md") if "_build" not in p.parts]
    missing = [str(p) for p in sources if not (site / p).is_file()]
    assert not missing and len(sources) >= 17, missing


def test_the_cli_reference_lists_every_command_and_its_options(site: Path):
    from pinstab.cli.commands import COMMANDS

    html = (site / "cli.html").read_text()
    for name in COMMANDS:
        assert f'id="pinstab-{name}"' in html, name
    for option in ("--method", "--integrator", "--rtol", "--stop-on", "--grid", "--memory-limit"):
        assert option in html, option


def test_the_api_reference_documents_the_public_names(site: Path):
    import pinstab

    html = (site / "api.html").read_text()
    undocumented = [name for name in pinstab.__all__ if not name.startswith("_") and f'id="pinstab.{name}"' not in html]
    assert not undocumented, undocumented


def test_the_mathematics_is_rendered_and_numbered(site: Path):
    html = (site / "mathematics.html").read_text()
    assert html.count('class="math') >= 100
    assert 'id="equation-eq-kkt"' in html and "(4)" in html  # eq. 4, the KKT system, as the docstrings cite it


def test_the_gallery_ran_its_examples(site: Path):
    """The executed examples show their output: every method's row, the multiplier against its closed form."""
    compare = (site / "auto_examples" / "compare_methods.html").read_text()
    for method in ("none", "baumgarte", "projection", "post", "pinocchio"):
        assert re.search(rf"\n{method}\s+\d\.\d\de-\d\d", compare), method
    user = (site / "auto_examples" / "user_constraint.html").read_text()
    error = float(re.search(r"closed form\| over 2 s: ([0-9.e+-]+) N", user).group(1))
    assert error < 1e-6
    for demo in ("allegro_lift", "recording", "stability_map"):
        assert (site / "auto_examples" / f"{demo}.html").is_file(), demo


def test_no_page_cites_math_md_outside_the_docs():
    """MATH.md is docs/mathematics.md: no reference to the old name is left in the sources or the pages."""
    stale = []
    for path in [ROOT / "README.md", *DOCS.rglob("*.md"), *(ROOT / "pinstab").rglob("*.py"), *(ROOT / "cpp").glob("*")]:
        if path.is_file() and "_build" not in path.parts and re.search(r"(?<![\w/])MATH\.md", path.read_text()):
            stale.append(str(path.relative_to(ROOT)))
    assert not stale, stale
