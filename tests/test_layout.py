"""The rules of ARCHITECTURE.md, read off the code's imports."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "dfrmot_jax"
MAX_LINES = 650


def _imports(path: Path) -> set[str]:
    """Package modules a file imports (relative imports resolved to dotted names under dfrmot_jax)."""
    tree = ast.parse(path.read_text())
    here = path.relative_to(PKG.parent).with_suffix("").parts          # ("dfrmot_jax", "core", "step")
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(here[:len(here) - node.level])
                mod = ".".join(base + ([node.module] if node.module else []))
                names = [mod] + [f"{mod}.{a.name}" for a in node.names]
            else:
                names = [node.module or ""]
            out.update(n for n in names if n.startswith("dfrmot_jax"))
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("dfrmot_jax"))
    return out


def test_core_imports_only_itself_and_config():
    for path in (PKG / "core").glob("*.py"):
        bad = {m for m in _imports(path) if not m.startswith(("dfrmot_jax.core", "dfrmot_jax.config"))}
        assert not bad, f"{path.name} imports {sorted(bad)}"


def test_the_oracle_imports_nothing_from_core():
    bad = {m for m in _imports(PKG / "testing" / "reference.py") if m.startswith("dfrmot_jax.core")}
    assert not bad, sorted(bad)


def test_nothing_in_the_package_imports_the_test_tools():
    for path in PKG.rglob("*.py"):
        if "testing" in path.relative_to(PKG).parts:
            continue
        bad = {m for m in _imports(path) if m.startswith("dfrmot_jax.testing")}
        assert not bad, f"{path.relative_to(PKG)} imports {sorted(bad)}"


def test_no_module_is_too_long():
    long = {str(p.relative_to(PKG)): n for p in PKG.rglob("*.py") if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, long
