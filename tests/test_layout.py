"""The code's map held to the tree: every package's docstring indexes its modules and sub-packages, a line each
("- name: ..." or "- name/: ..."), and docs/development/layout.md names every module by its path; a module added
without its line, or a line naming a module that is gone, fails here. No package holds more than MAX_MODULES. The
tests' own helpers live in helper modules or conftest.py, never in a test file another test imports."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(p.parent for top in ("rov_mav", "sim_bridge") for p in (ROOT / top).rglob("__init__.py")
                  if "data" not in p.relative_to(ROOT).parts)
INDEX_LINE = re.compile(r"^- (\w+)(/?): ", re.M)
MAX_MODULES = 12
LAYOUT = ROOT / "docs" / "development" / "layout.md"


def _contents(package: Path) -> set[str]:
    modules = {p.stem for p in package.glob("*.py") if p.name != "__init__.py"}
    rooms = {f"{p.name}/" for p in package.iterdir() if (p / "__init__.py").is_file()}
    return modules | rooms


def _index(package: Path) -> list[str]:
    doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
    return [name + slash for name, slash in INDEX_LINE.findall(doc)]


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_each_package_indexes_what_it_holds(package):
    index = _index(package)
    assert len(index) == len(set(index)), f"{package.relative_to(ROOT)}: a line twice in its index"
    held = _contents(package)
    assert set(index) == held, (f"{package.relative_to(ROOT)}/__init__.py: not indexed {sorted(held - set(index))}, "
                                f"indexed but missing {sorted(set(index) - held)}")
    modules = [n for n in held if not n.endswith("/")]
    assert len(modules) <= MAX_MODULES, f"{package.relative_to(ROOT)}: {len(modules)} modules (at most {MAX_MODULES})"


def test_the_layout_page_names_every_module_and_none_that_is_gone():
    listed = re.findall(r"^((?:rov_mav|sim_bridge)/[\w/]*\w\.py) ", LAYOUT.read_text(), flags=re.M)
    twice = sorted({path for path in listed if listed.count(path) > 1})
    assert not twice, f"{LAYOUT.name} lists modules more than once: {twice}"
    named = set(re.findall(r"\b((?:rov_mav|sim_bridge)/[\w/]*\w\.py)\b", LAYOUT.read_text()))
    tree = {str(p.relative_to(ROOT)) for top in ("rov_mav", "sim_bridge") for p in (ROOT / top).rglob("*.py")
            if p.name != "__init__.py"}
    assert not named - tree, f"{LAYOUT.name} names modules that are not in the tree: {sorted(named - tree)}"
    assert not tree - named, f"{LAYOUT.name} leaves out: {sorted(tree - named)}"


def test_no_test_file_imports_another():
    importing = {}
    for path in sorted((ROOT / "tests").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            if any(name.split(".")[0].startswith("test_") for name in names):
                importing[path.name] = names
    assert not importing, f"test files importing a test file (move the helpers to a *_helpers module): {importing}"


MAX_COMMAND_FUNCTION = 60        # lines: a command reads as parse, build, fly, report; the assembly lives elsewhere


def test_no_function_of_the_commands_is_longer_than_a_screen():
    import ast

    long = []
    for path in sorted((ROOT / "rov_mav" / "commands").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_COMMAND_FUNCTION:
                    long.append(f"{path.name}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, f"functions in rov_mav/commands over {MAX_COMMAND_FUNCTION} lines: {long}"
