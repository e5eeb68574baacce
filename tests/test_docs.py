"""The manual (docs/): it builds with warnings as errors, its links resolve, the reference holds every command and
option of the real parser, the README front page stays a front page, and the pages render in a browser with the
equations typeset.

The site is built once per session (about 5 s; the file takes about 10 s); the browser checks need Debian's `chromium`
and `chromium-driver`
(.ci/run installs them) and fail, not skip, without them.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import re
import shutil
import subprocess
import sys
import threading
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from rov_mav.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README_MAX_LINES = 150
CHROMIUM = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
CHROMEDRIVER = ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The built HTML site (sphinx-build -W --keep-going -n: any warning fails the build)."""
    out = tmp_path_factory.mktemp("docs") / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html", str(DOCS), str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=600)
    if proc.returncode != 0:
        pytest.fail(f"sphinx-build failed (status {proc.returncode}):\n{proc.stderr[-6000:]}")
    return out


@pytest.mark.process
def test_builds_without_warnings(site):
    assert (site / "index.html").is_file()
    assert (site / "first-dive.html").is_file()
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file(), "MathJax must ship with the site (offline)"


class _Links(HTMLParser):
    """Every href/src of a page, and every id it defines."""

    def __init__(self):
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("href", "src") and value:
                self.links.append(value)
            elif name in ("id", "name") and value:
                self.ids.add(value)


@functools.cache
def _parsed(path: Path) -> _Links:
    parser = _Links()
    parser.feed(path.read_text(encoding="utf-8", errors="replace"))
    return parser


@pytest.mark.process
def test_internal_links_resolve(site):
    broken = []
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 30
    for page in pages:
        if "_static" in page.parts or "_sources" in page.parts:
            continue
        for link in _parsed(page).links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
                continue
            target = page if not parts.path else (page.parent / unquote(parts.path)).resolve()
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{page.relative_to(site)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html" and unquote(parts.fragment) not in _parsed(target).ids:
                broken.append(f"{page.relative_to(site)}: {link} (no such anchor)")
    assert not broken, "broken links in the built site:\n" + "\n".join(broken)


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


@pytest.mark.process
def test_reference_has_every_subcommand_and_option(site):
    text = (site / "reference" / "cli.html").read_text(encoding="utf-8")
    text = re.sub(r"<[^>]+>", " ", text).replace("&#8212;", "--")
    subcommands = _subcommands(build_parser())
    assert len(subcommands) >= 9
    missing = []
    for name, sub in subcommands.items():
        if not re.search(rf"\b{re.escape(name)}\b", text):
            missing.append(name)
        for action in sub._actions:
            for option in action.option_strings:
                if option in ("-h", "--help"):
                    continue
                if not re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text):
                    missing.append(f"{name} {option}")
            if not action.option_strings and action.dest not in ("help",):
                if action.dest not in text and (action.metavar or "") not in text:
                    missing.append(f"{name} positional {action.dest}")
    assert not missing, "not in the generated reference: " + ", ".join(missing)


def test_readme_is_a_front_page_with_working_links():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = readme.splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; at most {README_MAX_LINES}"
    for command in ("make run", "make test"):
        assert command in readme
    targets = re.findall(r"\]\(([^)\s]+)\)", readme)
    assert any(t.startswith("docs/") for t in targets)
    broken = [t for t in targets
              if not urlsplit(t).scheme and not (ROOT / unquote(urlsplit(t).path)).exists()]
    assert not broken, f"README links to missing files: {broken}"


def _browser_paths() -> tuple[str, str]:
    chromium = next((p for p in CHROMIUM if Path(p).exists()), shutil.which("chromium"))
    driver = next((p for p in CHROMEDRIVER if Path(p).exists()), shutil.which("chromedriver"))
    if not chromium or not driver:
        pytest.fail("headless Chromium and its driver are needed to look at the manual: apt-get install chromium "
                    "chromium-driver (.ci/run does it)")
    return chromium, driver


@pytest.fixture(scope="module")
def served(site):
    """The site over HTTP on localhost, as a user's browser would load it."""
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    handler = functools.partial(Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.fixture(scope="module")
def browser():
    chromium, driver_path = _browser_paths()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,1600"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    driver.set_page_load_timeout(30)
    driver.set_script_timeout(30)
    yield driver
    driver.quit()


def _not_blank(png: Path) -> bool:
    from PIL import Image
    with Image.open(png) as image:
        colours = image.convert("RGB").getcolors(maxcolors=1 << 16)
    return colours is None or len(colours) > 20


PAGES = ["index.html", "first-dive.html", "explanation/model-and-law.html", "reference/cli.html"]


@pytest.mark.process
@pytest.mark.parametrize("page", PAGES)
def test_pages_render_in_a_browser(page, served, browser, tmp_path):
    browser.get(f"{served}/{page}")
    assert "rov-mav" in browser.title
    typeset = browser.execute_async_script("""
        const done = arguments[arguments.length - 1];
        if (!window.MathJax) { done(-1); return; }
        const ready = (MathJax.startup && MathJax.startup.promise) || Promise.resolve();
        ready.then(() => done(document.querySelectorAll('mjx-container').length), () => done(-2));
    """)
    shot = tmp_path / (page.replace("/", "_") + ".png")
    browser.save_screenshot(str(shot))
    assert shot.stat().st_size > 10_000 and _not_blank(shot), f"{page}: the screenshot {shot} is blank"
    visible = browser.execute_script("return document.body.innerText")
    assert len(visible) > 300, f"{page}: almost no text rendered"
    for raw in ("\\(", "\\[", "$$", "\\tag", "\\begin"):
        assert raw not in visible, f"{page}: raw LaTeX {raw!r} visible: the equations were not typeset"
    if page == "explanation/model-and-law.html":
        assert typeset >= 6, f"MathJax typeset {typeset} equations on the model page (needs the offline MathJax)"
        for number in ("(2.7)", "(2.17)", "(2.22)"):
            assert number in visible, f"equation {number} is not numbered as in the report"


OTHER_PROGRAMS = {   # options the manual quotes from other programs' command lines
    "--keep-going": "sphinx-build", "--dist": "pytest-xdist", "--maxschedchunk": "pytest-xdist",
    "--logfile": "MAVProxy", "--nthreads": "dask worker", "--nworkers": "dask worker", "--port": "dask scheduler",
    "--serve-grpc": "rerun",
}


def test_options_named_in_the_manual_exist():
    """A hand-written `--option` in any page or the README is one rov-mav's parser or one of tools/ has: an option
    renamed in the code fails here, not in a user's shell."""
    known = set(OTHER_PROGRAMS)

    def walk(parser):
        for action in parser._actions:
            known.update(action.option_strings)
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    walk(sub)

    walk(build_parser())
    tools = "".join(f.read_text(encoding="utf-8") for f in (ROOT / "tools").glob("*.py"))
    stale = []
    pages = [p for p in DOCS.rglob("*.md") if p.relative_to(DOCS).parts[0] not in ("_build", "bench", "report")]
    for page in [*pages, ROOT / "README.md"]:
        for option in set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]+)", page.read_text(encoding="utf-8"))):
            if option not in known and f'"{option}"' not in tools:
                stale.append(f"{page.relative_to(ROOT)}: {option}")
    assert not stale, "options the code does not have: " + ", ".join(sorted(stale))


def test_run_help_names_every_exit_status_the_runner_returns():
    """`rov-mav run --help` lists each exit status the runner can return, read from the constants it returns."""
    from rov_mav.commands.run import EPILOG
    from rov_mav.flight.run.thruster_watch import EXIT_THRUSTER
    from rov_mav.flight.session.vehicle_events import EXIT_FAILSAFE, EXIT_REBOOT

    statuses = " ".join(EPILOG.split()).split("exit status:")[1]
    for code in (0, 1, 2, 3, EXIT_THRUSTER, EXIT_REBOOT, EXIT_FAILSAFE):
        assert f"; {code} " in statuses or statuses.startswith(f" {code} "), code
