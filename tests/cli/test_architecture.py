"""The package's import graph has no cycle: each module's imports (top level and inside functions) form a DAG."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "urdf_pipeline"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The package modules `path` imports (`from . import x` names module x when x is a module)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            for alias in node.names:
                if f"{target}.{alias.name}" in modules:
                    found.add(f"{target}.{alias.name}")
                elif target in modules:
                    found.add(target)
        elif isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name in modules}
    found.discard(name)
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
    ("urdf_pipeline.review",),
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
