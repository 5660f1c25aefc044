"""The rules of ARCHITECTURE.md, read off the code's imports.

ARCHITECTURE.md's layout table is parsed here: its first column names each place of the package
(``config.py``, ``core/``, ...), its last column what the place may import (backticked places or
modules, ``everything above``, ``anything``, ``nothing``). The tests check the code against the
table in both directions (every import allowed, every allowance used, every module in a place), so
the document and the code cannot drift apart, and check the rules the table cannot say: no import
cycle, no underscore name imported across modules, the oracle's and the tracker's import closures.
"""

import ast
import re
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "dfrmot_jax"
MAX_LINES = 600
ORACLE = "dfrmot_jax.testing.reference"
REPORT = "dfrmot_jax.report"
#: third-party packages that are (or import) JAX
JAX_PACKAGES = ("jax", "jaxlib", "optax")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@lru_cache(maxsize=None)
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _targets(node, here: str, is_pkg: bool) -> list[tuple[str, str | None]]:
    """(imported package module, imported name or None) of one import statement."""
    mods = _modules()
    if isinstance(node, ast.Import):
        return [(a.name, None) for a in node.names if a.name.startswith("dfrmot_jax")]
    base = here.split(".") if is_pkg else here.split(".")[:-1]
    if node.level:
        mod = ".".join(base[:len(base) - node.level + 1] + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    if not mod.startswith("dfrmot_jax"):
        return []
    return [(f"{mod}.{a.name}", None) if f"{mod}.{a.name}" in mods else (mod, a.name) for a in node.names]


@lru_cache(maxsize=None)
def _graph() -> dict[str, dict[str, list]]:
    """module -> {imported module: [imported names]} over every import statement (lazy ones too)."""
    out = {}
    for name, path in _modules().items():
        edges: dict[str, list] = {}
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for mod, imported in _targets(node, name, path.name == "__init__.py"):
                    edges.setdefault(mod, []).append(imported)
        out[name] = edges
    return out


def _closure(start: set[str]) -> set[str]:
    """Every package module reachable from ``start`` through import statements (``start`` included;
    importing a module also runs the ``__init__`` of each package it sits in, except the package
    root's, which is the public entry point that imports everything and is no place's dependency,
    and the ``__init__`` of a package split into places (``metrics/``: the public API of the
    places inside it), which is no dependency of the places inside it either)."""
    seen, todo = set(), list(start)
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        parents = [".".join(m.split(".")[:i]) for i in range(1, m.count(".") + 1)]
        todo.extend(p for p in parents if p in _modules() and p != "dfrmot_jax" and not _above_place(p, m))
        todo.extend(_graph().get(m, {}))
    return seen


def _above_place(package: str, module: str) -> bool:
    """``package`` holds ``module``'s place without being it: a package split into places."""
    place = _place_of(module)
    return place != package and place.startswith(package + ".")


# ---------------------------------------------------------------------------------------------
# The table of ARCHITECTURE.md

def _place_key(cell: str) -> str:
    """``trackers/dfr/`` -> ``dfrmot_jax.trackers.dfr``; ``metrics/common/`` -> ``dfrmot_jax.metrics.common``;
    ``trackers/*/config.py`` -> ``dfrmot_jax.trackers.*.config``; ``__init__.py`` -> the root."""
    cell = cell.strip("`")
    if cell == "__init__.py":
        return "dfrmot_jax"
    return "dfrmot_jax." + cell.removesuffix("/").removesuffix(".py").replace("/", ".")


def _family_names() -> list[str]:
    """The tracker families: the folders under ``trackers/`` (each a package)."""
    return sorted(p.parent.name for p in (PKG / "trackers").glob("*/__init__.py"))


def _expand(place: str, family: str | None) -> list[str]:
    """A place or target with ``*`` (one family folder): the one of ``family`` (a row of a family's
    own), else every family's."""
    if "*" not in place:
        return [place]
    return [place.replace("*", f) for f in ([family] if family else _family_names())]


#: the machinery's rows: "everything above but the family folders (`trackers/*/`)"
BUT_FAMILIES = "but the family folders"


@lru_cache(maxsize=None)
def _table() -> list[tuple[str, set[str] | None]]:
    """[(place, allowed targets or None for anything)] in the table's order; ``everything above``
    expanded to the places of the rows above (``but the family folders``: without any place inside
    a family's folder); a row of ``trackers/*/...`` stands for each family's own (but for a family
    with a row of its own above), its ``*`` targets that family's."""
    text = (ROOT / "ARCHITECTURE.md").read_text()
    section = text.split("## Layout and rules", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    assert rows, "ARCHITECTURE.md has no layout table"
    out: list[tuple[str, set[str] | None]] = []
    for line in rows:
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        keys = [_place_key(p) for p in re.findall(r"`([^`]+)`", cells[0])]
        may = cells[-1]
        for key in keys:
            for family in (_family_names() if "*" in key else [None]):
                place = _expand(key, family)[0]
                if family and any(p == place for p, _ in out):
                    continue            # (a family with a row of its own above)
                allowed: set[str] | None = set()
                if may.startswith("anything"):
                    allowed = None
                else:
                    named = may.split(BUT_FAMILIES, 1)[0]
                    if "everything above" in named:
                        allowed |= {p for p, _ in out}
                        if BUT_FAMILIES in may:
                            allowed = {p for p in allowed if not any(_matches(p, f"dfrmot_jax.trackers.{f}")
                                                                     for f in _family_names())}
                    for t in re.findall(r"`([^`]+)`", named):
                        allowed |= set(_expand("dfrmot_jax." + t, family))
                out.append((place, allowed))
    return out


def _place_of(module: str) -> str:
    """The table's place a module belongs to (the longest key it sits under)."""
    keys = [p for p, _ in _table() if module == p or module.startswith(p + ".")]
    keys = [k for k in keys if k != "dfrmot_jax" or module == "dfrmot_jax"]
    assert keys, f"{module} is in no place of ARCHITECTURE.md's layout table"
    return max(keys, key=len)


def _matches(module: str, target: str) -> bool:
    return module == target or module.startswith(target + ".")


def test_every_module_sits_in_a_place_of_the_table_and_every_place_exists():
    mods = _modules()
    for m in mods:
        _place_of(m)
    for place, _ in _table():
        assert any(_matches(m, place) for m in mods), f"ARCHITECTURE.md names {place}, which does not exist"


def test_every_import_is_one_the_table_allows():
    table = dict(_table())
    bad = []
    for m, edges in _graph().items():
        place = _place_of(m)
        allowed = table[place]
        if allowed is None:
            continue
        for t in edges:
            if _place_of(t) == place or any(_matches(t, a) for a in allowed):
                continue
            bad.append(f"{m} imports {t} ({place} may import {sorted(a.removeprefix('dfrmot_jax.') for a in allowed)})")
    assert not bad, "\n".join(bad)


def test_every_allowance_of_the_table_is_used():
    """An allowance no module uses is a stale line of the document (``everything above`` excepted)."""
    text_rows = _table()
    stale = []
    for i, (place, allowed) in enumerate(text_rows):
        if allowed is None:
            continue
        above = {p for p, _ in text_rows[:i]}
        named = {a for a in allowed if a not in above or a in _named_targets(place)}
        used = {t for m, edges in _graph().items() if _place_of(m) == place for t in edges}
        for a in named:
            if not any(_matches(t, a) for t in used):
                stale.append(f"{place} may import {a}, but nothing of it does")
    assert not stale, "\n".join(stale)


def _named_targets(place: str) -> set[str]:
    """The targets a row names itself (not through ``everything above``)."""
    text = (ROOT / "ARCHITECTURE.md").read_text().split("## Layout and rules", 1)[1].split("\n## ", 1)[0]
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("| `"):
            continue
        for key in [_place_key(p) for p in re.findall(r"`([^`]+)`", cells[0])]:
            for family in (_family_names() if "*" in key else [None]):
                if _expand(key, family)[0] == place:
                    named = cells[-1].split(BUT_FAMILIES, 1)[0]
                    return {t for n in re.findall(r"`([^`]+)`", named) for t in _expand("dfrmot_jax." + n, family)}
    return set()


def test_the_table_holds_transitively():
    """What a place reaches through every chain of imports stays inside what its allowances reach."""
    table = dict(_table())

    def allowed_closure(place: str) -> set[str] | None:
        seen, todo = set(), [place]
        while todo:
            p = todo.pop()
            if p in seen:
                continue
            seen.add(p)
            allowed = table[_place_of(p)]
            if allowed is None:
                return None
            todo.extend(allowed)
            todo.append(_place_of(p))
        return seen

    bad = []
    for place, allowed in table.items():
        if allowed is None:
            continue
        reach = allowed_closure(place)
        if reach is None:
            continue
        start = {m for m in _modules() if _place_of(m) == place}
        for m in _closure(start):
            if not any(_matches(m, r) for r in reach):
                bad.append(f"{place} reaches {m}")
    assert not bad, "\n".join(sorted(bad))


# ---------------------------------------------------------------------------------------------
# Rules the table cannot say

METRIC_FAMILIES = ("dfrmot_jax.metrics.kitti2d", "dfrmot_jax.metrics.samota")
METRICS_COMMON = "dfrmot_jax.metrics.common"


def test_the_metric_families_meet_only_in_metrics_common():
    """TrackEval's family (``metrics/kitti2d/``) and AB3DMOT's (``metrics/ab3dmot/``) reach nothing of
    each other through any chain of imports, ``metrics/common/`` reaches neither, and both use it."""
    mods = _modules()
    bad = []
    for fam in METRIC_FAMILIES:
        other = [f for f in METRIC_FAMILIES if f != fam]
        reach = _closure({m for m in mods if _matches(m, fam)})
        bad += [f"{fam} reaches {m}" for m in sorted(reach) if any(_matches(m, o) for o in other)]
        assert any(_matches(m, METRICS_COMMON) for m in reach), f"{fam} uses nothing of {METRICS_COMMON}"
    reach = _closure({m for m in mods if _matches(m, METRICS_COMMON)})
    bad += [f"{METRICS_COMMON} reaches {m}" for m in sorted(reach) if any(_matches(m, f) for f in METRIC_FAMILIES)]
    assert not bad, "\n".join(bad)


#: DFR-FastMOT's tracker proper: its jittable step and the compiled batch
DFR_KERNEL = ("associate", "filters", "memory", "step", "run")


def test_dfrs_tracker_reaches_only_itself_its_config_and_the_shared_records():
    """DFR-FastMOT's tracker (``trackers/dfr/``: ``associate``, ``filters``, ``memory``, ``step``,
    ``run``) reaches its settings (``config``, with the protocol's records they are given as and the
    capacity policy), the shared records it steps over (``frames``, ``boxes``, ``rows``) and the
    platform it runs on (``devices``), nothing else."""
    kernel = {f"dfrmot_jax.trackers.dfr.{m}" for m in DFR_KERNEL}
    ok = kernel | {"dfrmot_jax.trackers.dfr", "dfrmot_jax.trackers.dfr.config", "dfrmot_jax.trackers.protocol",
                   "dfrmot_jax.trackers.capacity", "dfrmot_jax.devices", "dfrmot_jax.frames", "dfrmot_jax.boxes",
                   "dfrmot_jax.rows"}
    bad = sorted(m for m in _closure(kernel) if m not in ok)
    assert not bad, bad


def _family_folder(module: str) -> str | None:
    """The family whose folder ``module`` sits in, or None."""
    for f in _family_names():
        if _matches(module, f"dfrmot_jax.trackers.{f}"):
            return f
    return None


def test_the_oracle_reaches_nothing_of_the_tracker():
    """The NumPy oracle (``testing/reference.py``) imports nothing of DFR-FastMOT's folder but its
    settings (``config``) through any chain, so the parity tests compare two independent
    implementations."""
    bad = sorted(m for m in _closure({ORACLE}) if _family_folder(m) and not m.endswith(".config")
                 and m != "dfrmot_jax.trackers.dfr")
    assert not bad, f"the oracle reaches {bad} through {sorted(_graph()[ORACLE])}"


def test_families_import_no_other_family_and_no_report():
    """A family's folder imports nothing of another family's folder or of ``report/``, and nothing
    outside the family folders (but the registry, each family's settings only, and the package root,
    each folder by its name) imports a family's folder: the machinery names the protocol."""
    bad = []
    for m, edges in _graph().items():
        own = _family_folder(m)
        for t in edges:
            other = _family_folder(t)
            if own and other and other != own:
                bad.append(f"{m} (family {own}) imports {t} (family {other})")
            if own and _matches(t, REPORT):
                bad.append(f"{m} (family {own}) imports {t}")
            if not own and other and not _matches(m, "dfrmot_jax.testing") and m != "dfrmot_jax" \
                    and not (m == "dfrmot_jax.trackers.registry" and t.endswith(".config")):
                bad.append(f"{m} imports {t} of family {other}")
    assert not bad, "\n".join(bad)


def _imports_jax(module: str) -> bool:
    """Whether ``module`` has an import statement (anywhere in it) of JAX or of a package built on it."""
    for node in ast.walk(ast.parse(_modules()[module].read_text())):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
        if any(n == p or n.startswith(p + ".") for n in names for p in JAX_PACKAGES):
            return True
    return False


def test_the_report_reaches_no_jax_and_no_tracker():
    """``report/`` reads stored tables: nothing it reaches through any chain of imports (the
    ``__init__`` of every package on the way included) is a family's tracker (its settings,
    ``config``, are read through the registry) or imports JAX, so
    that ``dfrmot report`` starts without them (``tests/cli/test_cli_startup.py`` runs it where JAX
    cannot be imported)."""
    reach = _closure({m for m in _modules() if _matches(m, REPORT)})
    assert "dfrmot_jax.table_columns" in reach and "dfrmot_jax.metrics.kitti2d.evaluate" in reach
    bad = sorted(m for m in reach if (_family_folder(m) and not m.endswith(".config")) or _imports_jax(m))
    assert not bad, f"report/ reaches {bad}"


def test_no_import_cycle():
    graph = {m: set(e) for m, e in _graph().items()}
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph.get(v, ()):
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, cycles


def test_no_underscore_name_is_imported_across_modules():
    bad = [f"{m} imports {name} from {t}" for m, edges in _graph().items() for t, names in edges.items()
           for name in names if name and name.startswith("_") and not name.startswith("__") and t != m]
    assert not bad, "\n".join(bad)


#: the functions that may import a module of the package by name when they run (``importlib``): the
#: command line's per-command lazy import (ARCHITECTURE.md, "Lazy imports")
#: packages whose public API is imported on first use, in their ``__getattr__`` (PEP 562): the root, and
#: AB3DMOT's tracker, whose settings (``ab3dmot.config``) are read without JAX
LAZY_PACKAGES = ("dfrmot_jax", "dfrmot_jax.trackers.ab3dmot")
LAZY_COMMANDS = {"dfrmot_jax.cli": {"build_parser"}, "dfrmot_jax.cli.errors": {"run_later"},
                 "dfrmot_jax.trackers.registry": {"load_family"}}


def test_imports_sit_at_module_top_unless_an_optional_dependency_needs_them_lazy():
    """Only optional dependencies (Ray, Matplotlib, Optuna's plots, PyTorch, the TrackEval reference)
    are imported inside functions, and the package root's public API in its ``__getattr__`` (PEP
    562: ``import dfrmot_jax`` imports nothing heavy)."""
    optional = ("ray", "matplotlib", "optuna.visualization", "torch", "trackeval")
    bad = []
    for name, path in _modules().items():
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            if name in LAZY_PACKAGES and fn.name == "__getattr__":
                continue
            for node in ast.walk(fn):
                mods = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [("." * node.level) + (node.module or "")] if isinstance(node, ast.ImportFrom) else []
                for mod in mods:
                    if not any(mod == o or mod.startswith(o + ".") for o in optional):
                        bad.append(f"{name}:{node.lineno} imports {mod} inside {fn.name}()")
    assert not bad, "\n".join(bad)


def test_modules_are_imported_by_name_only_for_the_command_lines_lazy_import():
    """``importlib.import_module`` (an import the rules above cannot see) only where the command line
    imports a command's module when that command runs: ``cli.build_parser`` (the named command's
    parser module) and ``cli.errors.run_later`` (the module of a command whose parser is built
    without it); both take the module from ``cli.commands``' table; and the registry's ``load_family``,
    a family's tracker by the module name its config gives (settings are read without JAX)."""
    bad = []
    for name, path in _modules().items():
        tree = ast.parse(path.read_text())
        owners = {id(node): fn.name for fn in tree.body if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
                  for node in ast.walk(fn)}                       # node -> the module-level function it sits in
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and (getattr(node.func, "attr", None) == "import_module" or
                                               getattr(node.func, "id", None) in ("import_module", "__import__")):
                where = owners.get(id(node), "(module level)")
                if where not in LAZY_COMMANDS.get(name, ()):
                    bad.append(f"{name}:{node.lineno} imports a module by name in {where}")
    assert not bad, "\n".join(bad)


def test_nothing_in_the_package_imports_the_test_tools():
    bad = [f"{m} imports {t}" for m, edges in _graph().items() if not _matches(m, "dfrmot_jax.testing")
           for t in edges if _matches(t, "dfrmot_jax.testing")]
    assert not bad, bad


def test_every_package_says_what_it_exports():
    for name, path in _modules().items():
        if path.name == "__init__.py":
            assert "__all__" in path.read_text(), f"{name} has no __all__"


def test_no_module_is_too_long():
    long = {str(p.relative_to(PKG)): n for p in PKG.rglob("*.py") if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, long


#: the longest a function may be; a longer one says why on the line above its ``def`` ("over 80 lines")
MAX_FUNCTION_LINES = 80


def test_no_function_is_too_long_without_a_reason():
    long = {}
    for p in PKG.rglob("*.py"):
        text = p.read_text()
        lines = text.splitlines()
        for n in ast.walk(ast.parse(text)):
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = n.end_lineno - n.lineno + 1
                first = min([n.lineno] + [d.lineno for d in n.decorator_list])
                reason = first >= 2 and "over 80 lines" in lines[first - 2]
                if size > MAX_FUNCTION_LINES and not reason:
                    long[f"{p.relative_to(PKG)}:{n.lineno} {n.name}"] = size
    assert not long, long
