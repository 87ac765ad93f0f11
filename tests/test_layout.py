"""The house rules of the package layout (DESIGN.md): no private name crosses a package
boundary, the layers import downwards only, and no library module outgrows one reading."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("jaxfem", "identification", "updating")
LAYER = {name: i for i, name in enumerate(PACKAGES)}  # may import only from a lower or equal layer
MAX_LINES = 550


def _modules():
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            init = parts[-1] == "__init__"
            yield path, ".".join(parts[:-1] if init else parts), init


def _imports(path: Path, module: str, init: bool):
    """``(line, target module, names)`` of every import, relative ones resolved."""
    package = module if init else module.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield node.lineno, target, tuple(a.name for a in node.names)


def _owner(target: str) -> str:
    """The package a module belongs to: the dotted path up to its first private part."""
    parts = target.split(".")
    for i, p in enumerate(parts):
        if p.startswith("_"):
            return ".".join(parts[:i])
    return target


def violations() -> list[str]:
    found = []
    for path, module, init in _modules():
        package = module if init else module.rsplit(".", 1)[0]
        for line, target, names in _imports(path, module, init):
            top = target.split(".")[0]
            if top not in LAYER:
                continue
            where = f"{path.relative_to(ROOT)}:{line}"
            if LAYER[top] > LAYER[module.split(".")[0]]:
                found.append(f"{where}: {module} imports {target} from a layer above")
            owner = _owner(target)
            if owner != target and owner != package:
                found.append(f"{where}: private module {target} imported from outside {owner}")
            private = [n for n in names if n.startswith("_") and not (owner == package and owner != target)]
            if private and owner != package:
                found.append(f"{where}: private name(s) {', '.join(private)} of {target} imported by {module}")
    return found


def test_no_private_name_crosses_a_package_boundary():
    assert violations() == []


def test_the_checker_finds_a_private_import(tmp_path, monkeypatch):
    """The rule bites: a module importing another package's private module is named."""
    fake = tmp_path / "updating" / "cli"
    fake.mkdir(parents=True)
    (tmp_path / "updating" / "__init__.py").write_text("")
    (fake / "__init__.py").write_text("")
    (fake / "_x.py").write_text("from .._residuals import rows\nfrom jaxfem._eager import jit_over\nfrom . import _y\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    monkeypatch.setattr(__import__(__name__), "PACKAGES", ("updating",))
    found = violations()
    assert len(found) == 2 and "updating._residuals" in found[0] and "jaxfem._eager" in found[1]


@pytest.mark.parametrize("path", [p for p, _, _ in _modules()], ids=lambda p: str(p.relative_to(ROOT)))
def test_module_size(path):
    n = len(path.read_text().splitlines())
    assert n <= MAX_LINES, f"{path.relative_to(ROOT)} has {n} lines (at most {MAX_LINES}): split it by what it holds"


MAX_BODY = 60  # lines of a function's body after its docstring: one screen


def _long_functions(path: Path) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            doc = isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
                and isinstance(body[0].value.value, str)
            n = node.end_lineno - (body[0].end_lineno + 1 if doc else node.lineno) + 1
            if n > MAX_BODY:
                out.append(f"{node.name} (line {node.lineno}): {n} lines")
    return out


@pytest.mark.parametrize("path", [p for p, _, _ in _modules()], ids=lambda p: str(p.relative_to(ROOT)))
def test_functions_fit_on_one_screen(path):
    assert _long_functions(path) == [], f"{path.relative_to(ROOT)}: split these (at most {MAX_BODY} lines a body)"
