"""The package's shape: no import cycle, no upward import, packages used through their surface, small modules."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "urdf_pipeline"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The package modules `path` imports (`from . import x` names module x when x is a module)."""
    found: set[str] = set()
    for target, names in _absolute_imports(path):
        for alias in names:
            if f"{target}.{alias}" in modules:
                found.add(f"{target}.{alias}")
            elif target in modules:
                found.add(target)
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name in modules}
    found.discard(_module_name(path))
    return found


def test_no_import_cycle() -> None:
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(f) for f in files}
    graph = {_module_name(f): _imports(f, modules) for f in files}
    state: dict[str, int] = {}  # 1 visiting, 2 done
    cycles: list[list[str]] = []

    def visit(module: str, stack: list[str]) -> None:
        state[module] = 1
        for imported in sorted(graph[module]):
            if imported.startswith(module + "."):
                continue  # a package importing its own submodules is how packages work
            if state.get(imported) == 1:
                cycles.append([*stack[stack.index(imported) :], imported] if imported in stack else [module, imported])
            elif imported not in state:
                visit(imported, [*stack, imported])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


ARCHITECTURE = PACKAGE.parent / "ARCHITECTURE.md"
TABLE_HEADING = "## What each package may import"
TOP_LEVEL_MODULES = 8


def _member(span: str) -> str:
    """`config/` or `errors.py` (a table cell's code span) as a module name: urdf_pipeline.config, urdf_pipeline.errors."""
    return "urdf_pipeline" if span == "__init__.py" else "urdf_pipeline." + span.removesuffix("/").removesuffix(".py")


def may_import_table() -> list[tuple[tuple[str, ...], set[str]]]:
    """ARCHITECTURE.md's table, the one statement of the rule: each row's members (the code spans of its first cell)
    and the members it may import, from its second cell: code spans, `top level` (the first row's members), or
    `every row above`. A row may import its own members."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    assert TABLE_HEADING in text, f"ARCHITECTURE.md has no section {TABLE_HEADING!r}"
    rows: list[tuple[tuple[str, ...], set[str]]] = []
    for line in text.split(TABLE_HEADING, 1)[1].splitlines()[1:]:
        if line.startswith("## "):
            break
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if not line.startswith("|") or len(cells) < 2 or set(cells[0]) <= {"-", " "} or cells[0] == "package":
            continue
        members = tuple(_member(span) for span in re.findall(r"`([^`]+)`", cells[0]))
        allowed = {_member(span) for span in re.findall(r"`([^`]+)`", cells[1])}
        if "top level" in cells[1]:
            allowed |= set(rows[0][0] if rows else members)
        if "every row above" in cells[1]:
            allowed |= {name for earlier, _ in rows for name in earlier}
        assert members, f"ARCHITECTURE.md: a row of {TABLE_HEADING!r} names no module: {line}"
        rows.append((members, allowed | set(members)))
    return rows


def _row(module: str, rows: list[tuple[tuple[str, ...], set[str]]]) -> int:
    """The row of `module`: the longest member that names it or its package."""
    best = (-1, 0)
    for index, (members, _) in enumerate(rows):
        for name in members:
            if (module == name or (module.startswith(name + ".") and name != "urdf_pipeline")) and len(name) > best[1]:
                best = (index, len(name))
    assert best[0] >= 0, f"{module} is in no row of ARCHITECTURE.md's {TABLE_HEADING!r}: add it there"
    return best[0]


def test_the_may_import_table_only_looks_up() -> None:
    """A row may import only rows above it, so the rule itself has no cycle."""
    rows = may_import_table()
    downward = [
        f"{', '.join(members)} may import {target}"
        for index, (members, allowed) in enumerate(rows)
        for target in sorted(allowed - set(members))
        if _row(target, rows) >= index
    ]
    assert not downward, "ARCHITECTURE.md's table lets a row import one below it: " + "; ".join(downward)


def _within(target: str, names: set[str]) -> bool:
    """`target` is one of `names` or inside one of the packages among them (the root package names only itself)."""
    return any(target == name or (name != "urdf_pipeline" and target.startswith(name + ".")) for name in names)


def test_every_import_is_allowed_by_the_table() -> None:
    """Each module imports only what its row of ARCHITECTURE.md's table allows (the root package, the Python API, only
    where the table says so: no stage imports upward into it)."""
    rows = may_import_table()
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(f) for f in files}
    refused = [
        f"{_module_name(f)} -> {target}"
        for f in files
        for target in sorted(_imports(f, modules))
        if not _within(target, rows[_row(_module_name(f), rows)][1])
    ]
    assert not refused, "imports ARCHITECTURE.md's table does not allow (change the import, or the table): " + "; ".join(refused)


def test_no_module_imports_a_package_that_holds_it() -> None:
    """No upward import: a module never imports its own package's `__init__` or any above it (a package's surface is
    for other packages; the root's, for users)."""
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(f) for f in files}
    upward = [
        f"{_module_name(f)} -> {target}"
        for f in files
        for target in sorted(_imports(f, modules))
        if _module_name(f).startswith(target + ".") and not (f.name == "__init__.py" and _module_name(f) == target)
    ]
    assert not upward, "upward imports: " + "; ".join(upward)


def test_benchmarks_import_no_other_benchmark_in_a_cycle() -> None:
    """The benchmark scripts share helpers through `benchmarks/common.py`-style modules, never by importing each other
    both ways."""
    folder = PACKAGE.parent / "benchmarks"
    scripts = {path.stem: path for path in folder.glob("*.py")}
    graph = {
        name: {
            alias.name.split(".")[-1] if isinstance(node, ast.Import) else (node.module or "").split(".")[-1]
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(node, ast.Import | ast.ImportFrom)
            for alias in node.names
        }
        & set(scripts)
        for name, path in scripts.items()
    }
    both_ways = sorted(f"{a} <-> {b}" for a in graph for b in graph[a] if a < b and a in graph.get(b, set()))
    assert not both_ways, "benchmarks importing each other: " + "; ".join(both_ways)


def test_the_top_level_stays_small() -> None:
    top = sorted(path.name for path in PACKAGE.glob("*.py"))
    assert len(top) <= TOP_LEVEL_MODULES, f"{len(top)} modules at the top level: {', '.join(top)}"


MAX_MODULE_LINES = 450


def test_no_module_is_too_long() -> None:
    long = [
        f"{path.relative_to(PACKAGE.parent)}: {n}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES
    ]
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them by what they own): " + "; ".join(long)


# Module and package names that may repeat in different packages, each with why a reader cannot take one for the
# other. Empty: a shared name (two `viewer.py`, two `pictures.py`) made a reader guess which one an import meant.
SHARED_NAMES: frozenset[str] = frozenset()


def test_no_two_modules_share_a_name() -> None:
    """A module's or subpackage's name says what it does across the whole package (`render/headless_viewer.py`,
    `execute/viewer_delivery.py`; `review/plan_report/`, not a `plan` beside the `plan/` package), so a traceback, an editor tab or a
    grep names one thing; `__init__.py` aside."""
    by_name: dict[str, list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        named = path.parent if path.name == "__init__.py" else path
        if named != PACKAGE:
            by_name.setdefault(named.stem, []).append(str(named.relative_to(PACKAGE.parent)))
    shared = [", ".join(paths) for name, paths in sorted(by_name.items()) if len(paths) > 1 and name not in SHARED_NAMES]
    assert not shared, "modules or packages sharing a name (rename one to say what it does): " + "; ".join(shared)


# The packages whose `__init__` is a surface: every package of the table but `cli/` (the command line, which no one imports).
STAGE_PACKAGES = tuple(
    name.removeprefix("urdf_pipeline.")
    for members, _ in may_import_table()
    for name in members
    if (PACKAGE / name.removeprefix("urdf_pipeline.")).is_dir() and name != "urdf_pipeline.cli"
)


def _absolute_imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module imported from, names) for each `from X import names` in `path`, X made absolute."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            found.append((target, [alias.name for alias in node.names]))
    return found


def _stage_package(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "urdf_pipeline" and parts[1] in STAGE_PACKAGES else None


def test_other_packages_import_only_a_package_surface() -> None:
    """A stage's modules are private: another package imports the names its `__init__` exports, so a module can be
    split or renamed without touching its users."""
    reaching_in = []
    for path in sorted(PACKAGE.rglob("*.py")):
        own = _stage_package(_module_name(path))
        for target, _ in _absolute_imports(path):
            other = _stage_package(target)
            if other is not None and other != own and target != f"urdf_pipeline.{other}":
                reaching_in.append(f"{_module_name(path)} imports {target}")
    assert not reaching_in, "imports past a package's surface: " + "; ".join(reaching_in)


def test_no_module_imports_its_own_package_surface() -> None:
    """Inside a package, modules import their siblings: importing the package's own `__init__` is the hidden loop that
    function-local imports used to dodge."""
    modules = {_module_name(f) for f in PACKAGE.rglob("*.py")}
    inward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = _module_name(path)
        own = _stage_package(name)
        if own is None or path.name == "__init__.py":
            continue
        for target, names in _absolute_imports(path):
            if target == f"urdf_pipeline.{own}" and any(f"{target}.{n}" not in modules for n in names):
                inward.append(f"{name} imports {', '.join(names)} from its own package")
    assert not inward, "; ".join(inward)


def test_every_surface_name_resolves() -> None:
    import importlib

    missing = []
    for package in STAGE_PACKAGES:
        module = importlib.import_module(f"urdf_pipeline.{package}")
        missing += [f"urdf_pipeline.{package}.{name}" for name in module.__all__ if not hasattr(module, name)]
    assert not missing, "exported but not defined: " + ", ".join(missing)


def test_no_surface_name_is_also_a_module_name() -> None:
    """Once `pkg.name` is imported as a module, Python sets it on the package, so the lazy surface would hand out the
    module instead of the function of that name (a bug seen with `execute.model_stream`)."""
    clashes = []
    for package in STAGE_PACKAGES:
        folder = PACKAGE / package
        module = importlib.import_module(f"urdf_pipeline.{package}")
        clashes += [
            f"urdf_pipeline.{package}.{name}"
            for name in module.__all__
            if (folder / f"{name}.py").exists() or (folder / name / "__init__.py").exists()
        ]
    assert not clashes, "exported names that are also module names: " + ", ".join(clashes)


def test_each_surface_lists_its_names_once() -> None:
    """A package's public names are written once, as `from .module import name` under `if TYPE_CHECKING:`; `__all__`
    and the lazy `__getattr__` are derived from those lines by `lazy_surface`, never written out beside them."""
    from urdf_pipeline.package import surface_imports

    twice = []
    for package in STAGE_PACKAGES:
        source = (PACKAGE / package / "__init__.py").read_text(encoding="utf-8")
        names = surface_imports(source)
        assert names and "lazy_surface(__name__, __file__)" in source, f"urdf_pipeline.{package}: no one-list surface"
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
                twice.append(f"urdf_pipeline.{package}.{node.value}")
    assert not twice, "public names written a second time (derive them from the TYPE_CHECKING imports): " + ", ".join(twice)


def test_no_module_imports_another_modules_private_name() -> None:
    """A name with a leading underscore is its module's own: another module that needs it gets a public name."""
    found = [
        f"{_module_name(path)}: {alias.name}"
        for path in sorted(PACKAGE.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("urdf_pipeline"))
        for alias in node.names
        if alias.name.startswith("_")
        and not alias.name.startswith("__")
        or (alias.asname or "").startswith("_")
        and not (alias.asname or "").startswith("__")
    ]
    assert not found, "private names imported across modules: " + "; ".join(found)


OWNS_CELL = 420  # characters: one sentence; the details are the module docstrings'


def test_each_package_says_what_it_owns_in_one_sentence() -> None:
    text = ARCHITECTURE.read_text(encoding="utf-8")
    table = text[text.index("| package | owns |") :].split("\n\n")[0].splitlines()[2:]
    long = [row.split(" | ")[0] for row in table if len(row.split(" | ", 1)[1]) > OWNS_CELL]
    assert not long, f"'owns' cells over {OWNS_CELL} characters (say it in one sentence): " + ", ".join(long)
