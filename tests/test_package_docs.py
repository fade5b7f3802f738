"""Every package's docstring lists its modules, all of them and only them.

A package docstring (``__init__.py``) has a section that starts with a line ``Modules``
(``Modules (sub-command in brackets)``, optionally underlined with dashes) and lists one
entry a line: the name (``name`` or bare; a sub-package ends with ``/``), spaces, a
one-line description; a description's further lines are indented deeper, and a blank line
ends the section. The names must be exactly the package's modules (``*.py`` but
``__init__``/``__main__``) and sub-packages (folders with an ``__init__.py``).

The docstrings are read from the source (nothing is imported).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOP_PACKAGES = ("cellcal", "daq", "drivers", "presentation", "sim_drivers", "calibration")


def packages() -> list[Path]:
    """Every package of the project: the top packages and all their sub-packages."""
    found = []
    for top in TOP_PACKAGES:
        found += sorted(init.parent for init in (ROOT / top).rglob("__init__.py")
                        if "__pycache__" not in init.parts)
    return found


def contents(package: Path) -> set[str]:
    """The package's modules and sub-packages (``name/``)."""
    modules = {p.stem for p in package.glob("*.py") if not p.stem.startswith("__")}
    subs = {p.name + "/" for p in package.iterdir()
            if p.is_dir() and (p / "__init__.py").is_file()}
    return modules | subs


def module_list(package: Path) -> list[tuple[str, str]] | None:
    """(name, description) of each entry of the docstring's ``Modules`` section; None when
    the docstring has none."""
    tree = ast.parse((package / "__init__.py").read_text(encoding="utf-8"))
    lines = (ast.get_docstring(tree, clean=True) or "").splitlines()
    start = next((i for i, line in enumerate(lines) if re.match(r"Modules\b", line)), None)
    if start is None:
        return None
    body = lines[start + 1:]
    if body and re.fullmatch(r"-+", body[0].strip()):
        body = body[1:]
    entries: list[tuple[str, str]] = []
    indent = None
    for line in body:
        if not line.strip():
            break
        depth = len(line) - len(line.lstrip())
        if indent is None:
            indent = depth
        if depth < indent:
            break
        if depth == indent:  # an entry; deeper lines continue its description
            name, _, description = line.strip().partition(" ")
            entries.append((name.strip("`"), description.strip()))
    return entries


def owner(name: str, package: Path) -> str | None:
    """The other package of the project that has a module (or sub-package) ``name``."""
    for other in packages():
        if other != package and name in contents(other):
            return ".".join(other.relative_to(ROOT).parts)
    return None


PACKAGES = packages()


def test_every_top_package_is_found():
    assert {p.name for p in PACKAGES} >= set(TOP_PACKAGES)
    assert len(PACKAGES) > len(TOP_PACKAGES)  # sub-packages too


@pytest.mark.parametrize("package", PACKAGES,
                         ids=[".".join(p.relative_to(ROOT).parts) for p in PACKAGES])
def test_module_list_names_exactly_the_package_modules(package):
    name = f"{package.relative_to(ROOT).as_posix()}/__init__.py"
    entries = module_list(package)
    assert entries, f"{name}: its docstring has no `Modules` list"
    listed = [n for n, _ in entries]
    assert len(listed) == len(set(listed)), f"{name}: listed twice: " + ", ".join(
        sorted({n for n in listed if listed.count(n) > 1}))
    actual = contents(package)
    missing = sorted(actual - set(listed))
    extra = [f"{n} (a module of {owner(n, package)})" if owner(n, package) else n
             for n in sorted(set(listed) - actual)]
    assert not missing and not extra, (
        f"{name}'s module list: missing {missing or 'none'}; "
        f"not in the package: {extra or 'none'}")
    undescribed = [n for n, d in entries if not d]
    assert not undescribed, f"{name}: no description for {undescribed}"


def test_module_list_parser(tmp_path):
    """The parser reads both styles the docstrings use, and stops at a blank line."""
    def parse(doc: str):
        (tmp_path / "__init__.py").write_text(doc, encoding="utf-8")
        return module_list(tmp_path)

    assert parse('"""Title.\n\nModules\n-------\nalpha   one\n        more of one\n'
                 'beta/  two\n\nAfter.\n    ``gamma``  not an entry\n"""\n') == [
        ("alpha", "one"), ("beta/", "two")]
    assert parse('"""Title.\n\nModules (in brackets)\n    ``a``  [x] one\n    ``b/``    two\n"""'
                 ) == [("a", "[x] one"), ("b/", "two")]
    assert parse('"""No list."""\n') is None
