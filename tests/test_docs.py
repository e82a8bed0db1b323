"""The manual: its guides run, its exported names are documented, and it builds and renders.

The guides' Python examples are doctests: each page runs as written, with its printed output.
The exported names pass numpydoc's validation (the checks `docs/conf.py` asks Sphinx for). A
slow test builds the site and opens it in headless Chromium, following every internal link.
"""

import doctest
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import starsense

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)
GUIDES = [p for p in PAGES if ">>> " in p.read_text()]
# the checks `docs/conf.py` gives numpydoc_validation_checks (read from there, one list)
CONF = (DOCS / "conf.py").read_text() if (DOCS / "conf.py").is_file() else ""
CHECKS = set(re.findall(r'"([A-Z]{2}\d\d)"', CONF.split("numpydoc_validation_checks", 1)[-1]))

pytestmark = pytest.mark.skipif(not DOCS.is_dir(), reason="no manual (docs/) beside the tests")


@pytest.mark.parametrize("page", GUIDES, ids=[str(p.relative_to(DOCS)) for p in GUIDES])
@pytest.mark.slow
def test_guide_runs_as_written(page):
    """Every Python example of the manual runs, and prints what the page says it prints."""
    result = doctest.testfile(
        str(page), module_relative=False, optionflags=doctest.ELLIPSIS, verbose=False
    )
    assert result.failed == 0
    assert result.attempted > 0


def test_guides_with_code_exist():
    """The manual has runnable guides (the Python page at least): the test above means something."""
    assert any(p.name == "python.md" for p in GUIDES)


def exported_objects():
    """Every documented public object of the front door: the names, and availability's entries."""
    names = [
        f"starsense.{n}"
        for n in starsense.__all__
        if n != "availability" and callable(getattr(starsense, n))  # not __version__
    ]
    names += [f"starsense.analysis.availability.{n}" for n in ("static", "dynamic", "mission")]
    return names


@pytest.mark.parametrize("name", exported_objects())
def test_exported_name_passes_numpydoc_validation(name):
    """numpydoc validation, with the manual's checks, finds nothing wrong in the docstring."""
    validate = pytest.importorskip("numpydoc.validate").validate
    assert CHECKS >= {"PR01", "PR02", "RT01"}, "docs/conf.py no longer asks for the checks"
    errors = [f"{code}: {msg}" for code, msg in validate(name)["errors"] if code in CHECKS]
    assert errors == [], f"{name}: " + "; ".join(errors)


# what the README, the manual and the tests' docstrings must not carry: history, not product
ISSUE = re.compile(r"\b[Ii]ssues? #?\d+|(?<![\w&])#\d{1,4}\b")
HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b")
SHARED = re.compile(r"\.\./shared")


def product_texts():
    """The README, every manual page, and the docstrings of the test modules."""
    texts = [ROOT / "README.md", *PAGES]
    for path in texts:
        if path.is_file():
            yield path, path.read_text()
    for path in sorted((ROOT / "tests").rglob("test_*.py")):
        source = path.read_text()
        docstrings = re.findall(r'"""(.*?)"""', source, flags=re.S)
        yield path, "\n".join(docstrings)


def test_no_history_in_product_texts():
    """No issue numbers, commit hashes or workspace paths in the README, manual, test docstrings."""
    found = []
    for path, text in product_texts():
        for pattern in (ISSUE, HASH, SHARED):
            found += [f"{path.relative_to(ROOT)}: {m.group(0)!r}" for m in pattern.finditer(text)]
    assert found == []


def test_history_patterns_catch_what_they_must():
    """The patterns above find an issue number, a commit hash and the workspace path."""
    assert ISSUE.search("as issue 23 asked") and ISSUE.search("fixed in #41")
    assert HASH.search("landed in e43fb61") and SHARED.search("see ../shared/data")
    assert not HASH.search("seed 20240605") and not ISSUE.search("colour &#32;")


@pytest.mark.slow
def test_site_builds_and_renders_in_a_browser(tmp_path):
    """The manual builds with no warning; Chromium renders the index and a guide; links resolve."""
    pytest.importorskip("sphinx", reason="Sphinx is not installed (the dev extra has it)")
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    if not chromium or not driver_path:
        pytest.skip("no headless browser: install Debian's chromium and chromium-driver")
    out = tmp_path / "html"
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", DOCS, out],
        capture_output=True,
        text=True,
        check=False,
    )
    assert build.returncode == 0, build.stderr[-2000:]
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    service = webdriver.ChromeService(executable_path=driver_path)
    browser = webdriver.Chrome(options=options, service=service)
    try:
        pages = [out / "index.html", out / "guides" / "datasheet.html"]
        broken, seen = [], set()
        for page in pages:
            browser.get(page.as_uri())
            title = browser.find_element("css selector", "h1").text
            assert title, f"{page.name} rendered no title"
            links = [
                a.get_attribute("href") for a in browser.find_elements("css selector", "a[href]")
            ]
            for href in links:
                if not href.startswith("file://"):
                    continue
                target = Path(href.split("#", 1)[0].removeprefix("file://"))
                if target not in seen:
                    seen.add(target)
                    if not target.is_file():
                        broken.append(f"{page.name} -> {href}")
        assert seen, "no internal link found"
        assert broken == []
    finally:
        browser.quit()


def test_readme_is_a_front_page_not_a_manual():
    """The README stays short (what it does, the two commands, examples, where the manual is)."""
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150  # what it does, the two commands, a datasheet, a solve, a figure
    assert any("make docs" in line for line in lines)  # it says where the manual is
    text = "\n".join(lines)
    assert "zoo" not in text.replace("bench-zoo", "")  # the tuning zoo lives in the manual
    for path in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text):  # its figures exist
        assert (ROOT / path).is_file(), path
