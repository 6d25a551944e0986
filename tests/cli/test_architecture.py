"""The package's shape: no import cycle, no upward import, packages used through their surface, small modules."""

from __future__ import annotations

import ast
import importlib
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


# The stages, lowest first: a module may import its own stage and the stages before it, never a later one.
LAYERS = (
    ("urdf_pipeline", "urdf_pipeline.errors", "urdf_pipeline.plan", "urdf_pipeline.confine", "urdf_pipeline.progress"),
    ("urdf_pipeline.config",),
    ("urdf_pipeline.urdf",),
    ("urdf_pipeline.sources",),
    ("urdf_pipeline.compile",),
    ("urdf_pipeline.execute",),
    ("urdf_pipeline.dataset",),
    ("urdf_pipeline.render",),
    ("urdf_pipeline.review",),
    ("urdf_pipeline.scaffold",),
    ("urdf_pipeline.api",),
    ("urdf_pipeline.cli", "urdf_pipeline.examples", "urdf_pipeline.__main__"),
)
TOP_LEVEL_MODULES = 8


def _layer(module: str) -> int:
    """The stage of `module`: the longest layer prefix that names it or its package."""
    best = (-1, 0)
    for index, names in enumerate(LAYERS):
        for name in names:
            if (module == name or module.startswith(name + ".")) and len(name) > best[1]:
                best = (index, len(name))
    assert best[0] >= 0, f"{module} is in no layer: add it to LAYERS and to ARCHITECTURE.md"
    return best[0]


def test_no_upward_import() -> None:
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(f) for f in files}
    upward = [
        f"{_module_name(f)} -> {target}"
        for f in files
        for target in sorted(_imports(f, modules))
        if target != "urdf_pipeline" and _layer(target) > _layer(_module_name(f))
    ]
    assert not upward, "imports of a later stage: " + "; ".join(upward)


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
    `execute/live_viewer.py`; `review/plan_report/`, not a `plan` beside `plan.py`), so a traceback, an editor tab or a
    grep names one thing; `__init__.py` aside."""
    by_name: dict[str, list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        named = path.parent if path.name == "__init__.py" else path
        if named != PACKAGE:
            by_name.setdefault(named.stem, []).append(str(named.relative_to(PACKAGE.parent)))
    shared = [", ".join(paths) for name, paths in sorted(by_name.items()) if len(paths) > 1 and name not in SHARED_NAMES]
    assert not shared, "modules or packages sharing a name (rename one to say what it does): " + "; ".join(shared)


STAGE_PACKAGES = ("config", "urdf", "sources", "compile", "execute", "dataset", "render", "review", "scaffold", "api")


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


def test_urdf_knows_nothing_of_configs() -> None:
    """`urdf/` reads robot descriptions for anyone (init, tests, users' scripts): locations come in as `Where`s."""
    reaching = [
        f"{_module_name(path)} imports {target}"
        for path in sorted((PACKAGE / "urdf").rglob("*.py"))
        for target, _ in _absolute_imports(path)
        if _stage_package(target) == "config"
    ]
    assert not reaching, "; ".join(reaching)
