"""The documentation and the code tell the same story.

(a) ``docs/thesis.md`` maps exactly the thesis equations the code cites, and names
functions and files that exist; (b) the code cites equations in one form, ``eq. 3.25``
(no parentheses, no ranges, no bare lists); (c) the README holds exactly the two set-up
commands and CI runs the second; (d) every relative link in README.md and docs/*.md
resolves, anchors included.
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE = ("jaxfem", "identification", "updating", "benchmarks")
SETUP = (
    "python -m pip install -e . && jaxfem demo",
    'python -m pip install -e ".[test]" && python -m pytest -q -n 2',
)

# Anything that looks like an equation citation: eq/eqs/Eq, optional dot, parentheses.
_ANY = re.compile(r"\b[Ee]qs?\.?\s*\(?\s*\d+\.\d+")
# The one form: "eq. 3.25".
_ONE = re.compile(r"eq\. (\d+\.\d+)(?!\d)")
# After a number, a range or a bare list hides members: "–3.31", "/3.42", ", 3.21", " and 3.4".
_HIDDEN = re.compile(r"\)?\s*(?:[–—/-]|,|\band\b|\bor\b|\bto\b)\s*\(?\d+\.\d+")
_ROW = re.compile(r"^\| eq\. (\d+\.\d+) \|(.*)$", re.M)


def _code_files() -> list[Path]:
    return sorted(p for d in CODE for p in (ROOT / d).rglob("*.py"))


def _citations() -> tuple[dict[str, list[str]], list[str]]:
    """Equation → where cited (file:line), and the citations not in the one form."""
    cited: dict[str, list[str]] = {}
    bad: list[str] = []
    for path in _code_files():
        text = path.read_text(encoding="utf-8")
        for m in _ANY.finditer(text):
            where = f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}"
            one = _ONE.match(text, m.start())
            if one is None or one.end() < m.end():
                bad.append(f"{where}: {text[m.start():m.end() + 12]!r}")
                continue
            if _HIDDEN.match(text, one.end()):
                bad.append(f"{where}: {text[m.start():one.end() + 12]!r}")
            cited.setdefault(one.group(1), []).append(where)
    return cited, bad


def _thesis_rows() -> dict[str, str]:
    text = (ROOT / "docs" / "thesis.md").read_text(encoding="utf-8")
    rows = _ROW.findall(text)
    numbers = [n for n, _ in rows]
    assert len(numbers) == len(set(numbers)), f"docs/thesis.md lists an equation twice: {numbers}"
    return dict(rows)


def test_thesis_table_matches_code_citations():
    cited, _ = _citations()
    rows = _thesis_rows()
    not_mapped = {n: cited[n] for n in sorted(set(cited) - set(rows))}
    not_cited = sorted(set(rows) - set(cited))
    assert not not_mapped, f"cited in the code but missing from docs/thesis.md: {not_mapped}"
    assert not not_cited, f"in docs/thesis.md but cited nowhere in {CODE}: {not_cited}"


_MISSING = object()


def _resolve(name: str):
    """The object ``pkg.module.attr.attr`` names (longest importable module prefix), or
    _MISSING. A module that exists but fails to import raises."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        module = ".".join(parts[:i])
        try:
            obj = importlib.import_module(module)
        except ModuleNotFoundError as err:
            if err.name is None or not (module + ".").startswith(err.name + "."):
                raise  # a module that exists but imports something missing
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr, _MISSING)
            if obj is _MISSING:
                return _MISSING
        return obj
    return _MISSING


def _defined_in(obj) -> str | None:
    """Repository-relative file that defines ``obj``, where Python can tell."""
    if isinstance(obj, property):
        obj = obj.fget
    try:
        path = inspect.getsourcefile(inspect.unwrap(obj))
    except TypeError:
        return None
    if path is None:
        return None
    path = Path(path).resolve()
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else None


def test_thesis_table_names_existing_code():
    """Every file in a row exists, every dotted name resolves, and is defined in a file the
    row names (so the table follows code that moves)."""
    missing = []
    for number, row in _thesis_rows().items():
        files = re.findall(r"[\w/]+\.py\b", row)
        for path in files:
            if not (ROOT / path).is_file():
                missing.append(f"eq. {number}: file {path}")
        for name in re.findall(r"`((?:jaxfem|identification|updating)(?:\.\w+)+)`", row):
            obj = _resolve(name)
            if obj is _MISSING:
                missing.append(f"eq. {number}: {name}")
            elif (where := _defined_in(obj)) is not None and where not in files:
                missing.append(f"eq. {number}: {name} is defined in {where}, not in {files}")
    assert not missing, f"docs/thesis.md names code that does not exist or has moved: {missing}"


def test_one_citation_form_in_code():
    _, bad = _citations()
    assert not bad, "cite as 'eq. 3.25' (lowercase, no parentheses, one 'eq.' per equation, no ranges): " + "; ".join(bad)


@pytest.mark.parametrize(
    "text, ok",
    [("eq. 3.25", True), ("eq. 3.23, eq. 3.28", True), ("eq. 1.30 times 2ω", True),
     ("eq. 4.4, Figs. 4.24–4.26", True), ("eq. (3.21)", False), ("eqs. 3.23–3.31", False),
     ("eq. 3.23-3.31", False), ("Eq. 3.36 ties", False), ("eqs. 3.12, 3.21", False),
     ("eq. 3.12, 3.21", False), ("eq. 3.41/3.42", False), ("eqs.\n    3.43/3.44", False),
     ("eq 3.1", False), ("frequency 1.5 Hz", True)],
)
def test_citation_rule(text, ok, tmp_path, monkeypatch):
    """The rule itself, on examples of each form."""
    package = tmp_path / "jaxfem"
    package.mkdir()
    (package / "x.py").write_text(f'"""{text}"""\n', encoding="utf-8")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    monkeypatch.setattr(sys.modules[__name__], "CODE", ("jaxfem",))
    _, bad = _citations()
    assert (not bad) == ok, bad


def _section(text: str, heading: str) -> str:
    start = text.index(heading + "\n")
    end = text.find("\n## ", start + len(heading))
    return text[start:] if end < 0 else text[start:end]


def test_readme_setup_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", _section(readme, "## Set up"), re.S | re.M)
    assert [b.strip() for b in blocks] == list(SETUP)
    installs = [line.strip() for line in readme.splitlines() if "pip install" in line and line.startswith("python")]
    assert installs == list(SETUP), f"set-up commands in the README: {installs}"
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    commands = [line.strip() for line in ci.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert commands[-1] == SETUP[1], f".ci/run runs {commands[-1]!r}"


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.S | re.M)
    return {_slug(h) for h in re.findall(r"^#+ (.+)$", text, re.M)}


def test_relative_links_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    broken = []
    for page in pages:
        text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue  # http:, https:, mailto:
            file, _, anchor = target.partition("#")
            dest = (page.parent / file).resolve() if file else page
            if not dest.exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such heading)")
    assert not broken, f"broken links: {broken}"
