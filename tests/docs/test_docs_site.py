"""The documentation site: built once with ``mkdocs build --strict`` (which must pass), then as readers see it,
served over HTTP and opened in headless Chromium through Selenium. Every page renders with no console error and
no failed request (the site asks nothing of another host), every image on it loads, and the search finds a function
by its name. Skips, saying why, where Selenium, Chromium or its driver, or the docs extra is missing
(Debian: ``apt-get install chromium chromium-driver``; ``pip install selenium``)."""

import functools
import http.server
import importlib.util
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BROWSER = next(filter(None, map(shutil.which, ("chromium", "chromium-browser", "google-chrome"))), None)
DRIVER = shutil.which("chromedriver")

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
    reason="the docs extra (mkdocs-material, mkdocstrings[python]) is not installed")
#: the browser tests' own conditions (the strict build runs without a browser)
NEEDS_BROWSER = [
    pytest.mark.skipif(importlib.util.find_spec("selenium") is None, reason="selenium is not installed"),
    pytest.mark.skipif(BROWSER is None or DRIVER is None,
                       reason="no Chromium and chromedriver (Debian: apt-get install chromium chromium-driver)"),
]

#: a function's name typed into the search box -> the page whose entry the first results must include
SEARCHES = {"to_statespace": "Systems and files", "save_sweep": "Studies and simulation"}


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The built site served on a free local port: (base URL, site folder)."""
    folder = tmp_path_factory.mktemp("site")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(folder)],
                          cwd=ROOT, capture_output=True, text=True, check=False, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(QuietHandler, directory=str(folder)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/", folder
    server.shutdown()


@pytest.fixture(scope="module")
def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    # no back/forward cache: it serves only history navigation (Back, Forward), which no check here uses (each page
    # is a new navigation, loaded in full either way); kept, it holds every left page alive (with the rendering
    # check's held search workers: about a third of that check's Chromium CPU)
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--disable-features=BackForwardCache"):
        options.add_argument(flag)
    options.binary_location = BROWSER
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(DRIVER))
    yield driver
    driver.quit()


def test_mkdocs_build_strict(site):
    """``mkdocs build --strict`` passes (the site fixture asserts it) and builds the API pages."""
    _, folder = site
    assert (folder / "api" / "solve" / "index.html").exists()


def _pages(folder: Path) -> dict[str, str]:
    """Each built page's path (relative to the site) -> its HTML."""
    return {p.relative_to(folder).as_posix(): p.read_text(encoding="utf-8") for p in folder.rglob("index.html")}


def _api_ids(folder: Path) -> set[str]:
    """The identifiers the API pages anchor (one per documented module, class, function, method, attribute)."""
    return {i for p in (folder / "api").rglob("index.html")
            for i in re.findall(r'id="(packetloss_cvx[\w.]*)"', p.read_text(encoding="utf-8"))}


#: a Sphinx role left in a docstring, as the page shows it (mkdocstrings does not read them)
SPHINX_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj):(?:<code>|`)")


def test_no_sphinx_role_shows_and_cross_references_are_links(site):
    """The API pages show no ``:func:`name``` text; their cross-references are autorefs links (a link whose target
    has no anchor fails the strict build)."""
    _, folder = site
    pages = _pages(folder)
    shown = {page: SPHINX_ROLE.findall(html) for page, html in pages.items() if SPHINX_ROLE.search(html)}
    assert not shown, {page: len(found) for page, found in shown.items()}
    links = sum(html.count('class="autorefs autorefs-internal"') for page, html in pages.items()
                if page.startswith("api/"))
    assert links >= 200


def test_formulas_are_typeset_by_mathjax_served_from_the_site(site):
    """Every page loads MathJax (its configuration first) from the site itself; numpydoc ``.. math::`` directives
    become arithmatex blocks, which MathJax typesets."""
    _, folder = site
    pages = _pages(folder)
    for page, html in pages.items():
        scripts = re.findall(r'<script src="([^"]+)"', html)
        names = [src.rsplit("/", 1)[-1] for src in scripts]
        assert "mathjax-config.js" in names, page
        assert "tex-chtml.js" in names, page
        assert names.index("mathjax-config.js") < names.index("tex-chtml.js"), page
        assert not [src for src in scripts if "://" in src], page             # nothing from another host
    assert (folder / "javascripts" / "mathjax" / "tex-chtml.js").stat().st_size > 10**6
    assert list((folder / "javascripts" / "mathjax" / "output" / "chtml" / "fonts" / "woff-v2").glob("*.woff"))
    assert not [page for page, html in pages.items() if ".. math::" in html]
    assert pages["api/solve/index.html"].count('<div class="arithmatex">') >= 5


def test_lists_are_lists_and_starred_symbols_are_not_emphasis(site):
    """A Markdown list written straight after a paragraph line runs into the paragraph (Python-Markdown wants a
    blank line): no paragraph holds a line starting ``- ``; the claims page's "In plain words" lists are lists. Two
    starred symbols in a paragraph (``J*_udp - J*_tcp``) would open and close emphasis inside words."""
    _, folder = site
    pages = _pages(folder)
    run_together = {page for page, html in pages.items()
                    for body in re.findall(r"<p>((?:(?!</p>).)*)</p>", html, flags=re.S)
                    if re.search(r"\n\s*(?:[-*+]|\d+\.) \S", body)}
    assert not run_together
    claims = pages["claims/index.html"]
    for heading in ("Rely on:", "Do not rely on:"):
        assert re.search(rf"<strong>{heading}</strong></p>\s*<ul>", claims), heading
    intraword = {page: re.findall(r".{20}\w<em>.{20}", html) for page, html in pages.items()
                 if re.search(r"\w<em>", html)}
    assert not intraword


#: internals the API pages must not document (module-private by use, public only for the package's own imports)
INTERNALS = ["packetloss_cvx.model.system.CacheKey", "packetloss_cvx.model.system.StructureStore",
             "packetloss_cvx.model.system.SystemStore", "packetloss_cvx.model.system.check_system",
             "packetloss_cvx.studies.engine.chunks", "packetloss_cvx.studies.output.csv_number",
             "packetloss_cvx.montecarlo.channels.sample_deliveries", "packetloss_cvx.qp.shared.padded"]


def test_api_pages_document_the_public_names_and_no_internals(site):
    """The closed loop has its entries, the figures page every ``plot_*`` of the package, the results page every
    result type; no private name (``_x``) and none of the internals has one."""
    import packetloss_cvx.plots
    import packetloss_cvx.results

    _, folder = site
    ids = _api_ids(folder)
    leaves = {i.rsplit(".", 1)[-1] for i in ids}
    closed_loop = {"simulate", "closed_loop", "dp_riccati", "critical_mu", "membership", "closed_loop_statespace",
                   "region_map", "stability_allocate"}
    assert closed_loop <= leaves
    plots = set(packetloss_cvx.plots.figures.__all__)
    assert len(plots) == 13
    assert {f"packetloss_cvx.plots.figures.{name}" for name in plots} <= ids
    assert {f"packetloss_cvx.results.{name}" for name in packetloss_cvx.results.__all__} <= ids
    assert not [i for i in ids if any(part.startswith("_") and not part.startswith("__") for part in i.split("."))]
    assert not set(INTERNALS) & ids


def test_no_docstring_paragraph_shows_as_a_parameter_or_exception(site):
    """A paragraph written after a numpydoc section (``Raises``, ``Attributes``) is read as one more entry of it: its
    first words show as a parameter's or an exception's name. Entry names are names, types or tuples of them."""
    _, folder = site
    misread = [(page.parent.name, re.sub("<[^>]+>", "", name)) for page in (folder / "api").rglob("index.html")
               for name in re.findall(r'<tr class="doc-section-item">\s*<td>\s*<code>(.*?)</code>',
                                      page.read_text(encoding="utf-8"), flags=re.S)
               if ": " in re.sub("<[^>]+>", "", name) or re.sub("<[^>]+>", "", name).rstrip().endswith(".")]
    assert not misread


#: a page's search worker and the index it is given, as absolute URLs, resolved as Material's bundle does (its
#: ``__config``: ``search`` the worker's script, ``base`` the site's root, whose ``search/search_index.json`` the page
#: fetches and posts to the worker)
SEARCH_URLS = ("const c = JSON.parse(document.getElementById('__config').textContent);"
               "return [new URL(c.search, location).href,"
               "        new URL('search/search_index.json', new URL(c.base, location)).href]")


@NEEDS_BROWSER[0]
@NEEDS_BROWSER[1]
def test_every_page_renders_without_console_errors_and_its_images_load(site, browser):
    """Every page loaded in full, as a reader opens it: its HTML, styles, scripts, images and the search index it
    fetches. The home page (first) runs its search worker as a reader's browser does; on the other pages the
    worker is created but held at its first line (Chromium's ``waitForDebuggerOnStart``): it is the same script
    given the same index (asserted: both URLs are the home page's), so building that index again, about 40 % of
    this test's CPU, would run the same computation 21 more times (the search tests below build it and query it).
    """
    base, folder = site
    pages = sorted(p.parent.relative_to(folder).as_posix() for p in folder.rglob("index.html"))
    assert len(pages) >= 20
    assert "cli" in pages
    assert pages[0] == "."
    problems = {}
    home_search = None
    try:
        for page in pages:
            browser.get(base + ("" if page == "." else page + "/"))
            errors = [entry["message"] for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]
            broken, article, search = browser.execute_script(     # one round trip: broken images, article, search
                "const a = document.querySelector('article');"
                "return [Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src),"
                "        a ? a.innerText : '', (() => {" + SEARCH_URLS + "})()]")
            if home_search is None:
                home_search = search                        # the home page's worker ran; hold the others' from now
                browser.execute_cdp_cmd("Target.setAutoAttach",
                                        {"autoAttach": True, "waitForDebuggerOnStart": True, "flatten": True})
            if errors or broken or not article.strip() or search != home_search:
                problems[page] = {"console": errors, "images": broken, "empty": not article.strip(),
                                  "search": search}
    finally:
        browser.execute_cdp_cmd("Target.setAutoAttach", {"autoAttach": False, "waitForDebuggerOnStart": False})
    assert not problems, problems


@pytest.fixture(scope="module")
def search_box(site, browser):
    """The home page loaded once with its search overlay open (the page's search index is built once, not once
    per name: about 0.5 s a load); each test empties the box and waits for the results to clear first."""
    from selenium.webdriver.common.by import By

    base, _ = site
    browser.get(base)
    browser.execute_script("document.getElementById('__search').checked = true")   # open the search overlay
    return browser.find_element(By.CSS_SELECTOR, "input[data-md-component=search-query]")


@pytest.mark.parametrize("name", sorted(SEARCHES))
@NEEDS_BROWSER[0]
@NEEDS_BROWSER[1]
def test_the_search_finds_a_function_by_its_name(browser, search_box, name):
    from selenium.common.exceptions import TimeoutException
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import WebDriverWait

    search_box.send_keys(Keys.CONTROL, "a")
    search_box.send_keys(Keys.BACKSPACE)            # an empty query: the previous name's results go
    WebDriverWait(browser, 20).until(lambda b: not b.find_elements(By.CSS_SELECTOR, ".md-search-result__item"))
    search_box.send_keys(name)
    seen: list[str] = []

    def top_five(b) -> bool:
        """The first five results' texts (present before the overlay has faded in), read in one script call: the
        box is typed a key at a time and the index is already built, so the results of a prefix of the name show
        first and are replaced (a result element read across that replacement went stale)."""
        seen[:] = b.execute_script(
            "return Array.from(document.querySelectorAll('.md-search-result__item')).slice(0, 5)"
            ".map(r => r.textContent)")
        return any(SEARCHES[name] in text and name in text for text in seen)

    try:
        WebDriverWait(browser, 20).until(top_five)
    except TimeoutException:
        pass
    assert any(SEARCHES[name] in text and name in text for text in seen), seen
