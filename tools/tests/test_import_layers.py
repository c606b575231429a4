"""The rig's layers, checked from the source: every import of rig/hilrig, dashboards/ and tools/
(at the top, inside functions, under TYPE_CHECKING: a deferred import is still a dependency)
makes an edge of one module graph, which must have no cycle, and whose edges go down the layers
only. The dashboards import one leaf of hilrig, the entity paths, so the rig can load them
without the dashboards pulling the rig back in.

The layer order lives here, once: a module may import its own layer and the layers below it.
The rig's public modules, all a tool may import of it, live in docs/architecture.md, once.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ARCHITECTURE = ROOT / "docs" / "architecture.md"
PUBLIC_BEGIN, PUBLIC_END = "<!-- public-modules: begin -->", "<!-- public-modules: end -->"

LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    # (layer, module prefixes), bottom up; a module belongs to the layer of its longest prefix.
    (
        "base",
        (
            "hilrig",
            "hilrig.errors",
            "hilrig.resources",
            "hilrig.table",
            "hilrig.expect",
            "hilrig.observe.paths",
            "hilrig.observe.layout",
        ),
    ),
    ("dashboards", ("dashboards",)),
    ("wire", ("hilrig.wire",)),
    ("plants", ("hilrig.plants",)),
    ("engine", ("hilrig.engine",)),
    ("observe", ("hilrig.observe",)),
    ("session", ("hilrig.session",)),
    ("apps", ("hilrig.apps",)),
    ("cli", ("hilrig.cli", "hilrig.__main__", "dashboards.__main__", "hilrig.pytest_plugin", "hilrig.lab")),
    ("tools", ("tools",)),
)
"""Base: the table, the errors, where the board's files are, the condition waiter, the entity
paths and the layout pieces (leaves every layer may name). The dashboards sit right above it:
they build Rerun layouts on the entity paths, and the tracer and the session load them.
`python -m hilrig` and `python -m dashboards` are entry points on top of the CLI; the pytest
plugin is one beside it (it runs the `hilrig` command on a scenario's bus), and so is hilrig.lab,
labgrid's resources and driver for a CAN bus (labgrid loads it)."""

DASHBOARDS_MAY_IMPORT = frozenset({"hilrig.observe.paths", "hilrig.observe.layout"})
"""The two leaves of hilrig the dashboards import (the entity paths, the layout pieces the checks
share) (entry points aside: `dashboards.__main__` is
the older spelling of `hilrig view` and nothing imports it)."""

PATHS_MAY_IMPORT = frozenset({"hilrig.errors"})
"""What the entity paths may import of hilrig: only the exception tree (its typo errors), itself
a leaf."""


def source_files() -> Iterator[tuple[str, Path]]:
    """(module name, file) of every .py file in the graph."""
    for path in sorted((ROOT / "rig" / "hilrig").rglob("*.py")):
        yield _dotted(path.relative_to(ROOT / "rig")), path
    for path in sorted((ROOT / "dashboards").rglob("*.py")):
        yield _dotted(path.relative_to(ROOT)), path
    for path in sorted((ROOT / "tools").rglob("*.py")):
        yield _dotted(path.relative_to(ROOT)), path


def _dotted(relative: Path) -> str:
    parts = list(relative.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _tool_module(name: str, modules: set[str]) -> str | None:
    """tools/ are scripts on their own folder's path: `import bench_common` is tools.bench_common."""
    candidate = f"tools.{name}"
    return candidate if candidate in modules else None


def imports(module: str, path: Path, modules: set[str]) -> set[str]:
    """The modules of the graph `module` imports, anywhere in its file."""
    found: set[str] = set()
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module or ""
            targets = [f"{prefix}.{alias.name}" for alias in node.names] + [prefix]
            # `from a.b import c`: the module a.b.c when c is one, else a.b itself
            submodules = [t for t in targets[:-1] if _resolve(t, modules) == t]
            targets = submodules if len(submodules) == len(node.names) else [*submodules, prefix]
        else:
            continue
        for target in targets:
            resolved = _resolve(target, modules)
            if resolved is None and module.startswith("tools"):
                resolved = _tool_module(target.split(".")[0], modules)
            if resolved is not None and resolved != module:
                found.add(resolved)
    return found


def _resolve(name: str, modules: set[str]) -> str | None:
    """The longest module of the graph that `name` names (itself, or a package above it)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def module_graph() -> dict[str, set[str]]:
    files = dict(source_files())
    # The C extensions (hilrig.wire._wire, hilrig.plants._plant) are modules too, importing nothing.
    extensions = {_dotted(c.relative_to(ROOT / "rig")) for c in (ROOT / "rig" / "hilrig").rglob("*.c")}
    modules = set(files) | extensions
    graph = {module: imports(module, path, modules) for module, path in files.items()}
    return graph | {module: set() for module in extensions}


def layer_of(module: str) -> int:
    best, best_len = None, -1
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best_len:
                best, best_len = index, len(prefix)
    assert best is not None, f"{module} is in no layer: add it to LAYERS"
    return best


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as [a, b, ..., a], or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == 1:
                return [*path[path.index(target) :], target]
            if target not in state and (cycle := visit(target)) is not None:
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)) is not None:
            return cycle
    return None


def test_the_graph_sees_the_known_modules_and_their_deferred_imports() -> None:
    graph = module_graph()
    assert {"hilrig.observe.paths", "hilrig.engine.rig", "dashboards.joint", "tools.bench"} <= set(graph)
    # a deferred import (inside a function) is an edge too
    assert "hilrig.apps.soak.run" in graph["hilrig.cli.soak"]


def test_no_import_cycle() -> None:
    cycle = find_cycle(module_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or ())


def test_imports_go_down_the_layers() -> None:
    graph = module_graph()
    upward = [
        f"{module} ({LAYERS[layer_of(module)][0]}) imports {target} ({LAYERS[layer_of(target)][0]})"
        for module, targets in sorted(graph.items())
        for target in sorted(targets)
        if layer_of(target) > layer_of(module)
    ]
    assert upward == []


def test_dashboards_import_only_the_leaves_of_hilrig() -> None:
    graph = module_graph()
    wrong = {
        module: sorted(t for t in targets if t.startswith("hilrig") and t not in DASHBOARDS_MAY_IMPORT)
        for module, targets in graph.items()
        if module.startswith("dashboards") and module != "dashboards.__main__"
    }
    assert {module: targets for module, targets in wrong.items() if targets} == {}
    paths = {t for t in graph["hilrig.observe.paths"] if t.startswith("hilrig")}
    assert paths <= PATHS_MAY_IMPORT
    assert not any(t.startswith("hilrig") for t in graph["hilrig.observe.layout"])
    assert not any(t.startswith("hilrig") for t in graph["hilrig.errors"])


def test_each_layer_folder_says_what_lives_there_and_imports_nothing() -> None:
    # plants/ names its interface in its __init__ (`from hilrig.plants import JointPlant`); cli/'s
    # __init__ is the command itself.
    for folder in ("wire", "engine", "session", "observe", "apps"):
        init = ROOT / "rig" / "hilrig" / folder / "__init__.py"
        tree = ast.parse(init.read_text())
        assert ast.get_docstring(tree), f"{init}: no docstring"
        assert not [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))], (
            f"{init} imports: importing one module of the layer would load them all"
        )


def test_the_rig_top_level_has_at_most_12_modules() -> None:
    top = sorted(p.name for p in (ROOT / "rig" / "hilrig").glob("*.py"))
    assert len(top) <= 12, top


def public_modules() -> tuple[str, ...]:
    """The rig's public modules as docs/architecture.md lists them between its two markers, each
    the first cell of a table row; "pkg.*" is pkg and every module under it."""
    text = ARCHITECTURE.read_text()
    listed = text[text.index(PUBLIC_BEGIN) : text.index(PUBLIC_END)]
    return tuple(re.findall(r"^\| `([\w.*]+)` \|", listed, re.MULTILINE))


def is_public(module: str, public: tuple[str, ...]) -> bool:
    return any(
        module == entry.removesuffix(".*") or (entry.endswith(".*") and module.startswith(entry[:-1]))
        for entry in public
    )


def tool_scripts() -> Iterator[Path]:
    """Every file of tools/ but its tests: the Python scripts and the others (shell, which may run
    Python with -m or -c)."""
    for path in sorted((ROOT / "tools").rglob("*")):
        if path.is_file() and "tests" not in path.relative_to(ROOT / "tools").parts:
            yield path


def _is_python(path: Path) -> bool:
    if path.suffix == ".py":
        return True
    with path.open("rb") as file:
        first = file.readline()
    return first.startswith(b"#!") and b"python" in first


_SHELL_HILRIG = re.compile(r"(?:-m\s+|\bimport\s+|\bfrom\s+)(hilrig(?:\.\w+)*)")
"""A module of hilrig a shell script names to Python: `python -m hilrig.x`, `-c "import hilrig.x"`."""


def hilrig_imports(path: Path, modules: set[str]) -> list[tuple[int, str]]:
    """(line, module) of every module of hilrig `path` imports (a Python file: every import
    statement, deferred ones too; another script: what it hands Python with -m or -c)."""
    found: list[tuple[int, str]] = []
    if not _is_python(path):
        text = path.read_text(errors="replace")
        for number, line in enumerate(text.splitlines(), 1):
            code = line.split("#", 1)[0]  # a comment naming a module imports nothing
            found += [(number, _resolve(m, modules) or m) for m in _SHELL_HILRIG.findall(code)]
        return found
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            # `from a.b import c`: the module a.b.c when c is one, else a.b itself
            names = [
                f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in modules else node.module
                for alias in node.names
            ]
        else:
            continue
        found += [
            (node.lineno, _resolve(name, modules) or name)
            for name in names
            if name == "hilrig" or name.startswith("hilrig.")
        ]
    return found


def test_the_public_modules_are_listed_once_and_exist() -> None:
    public = public_modules()
    assert "hilrig.cli" in public and "hilrig.apps.*" in public, public
    assert len(set(public)) == len(public), public
    modules = set(module_graph())
    assert [m for m in public if m.removesuffix(".*") not in modules] == []


def test_tools_import_only_the_rigs_public_modules() -> None:
    public, modules = public_modules(), set(module_graph())
    wrong = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}, not a public module of hilrig "
        f"(docs/architecture.md)"
        for path in tool_scripts()
        for line, module in hilrig_imports(path, modules)
        if not is_public(module, public)
    ]
    assert wrong == []


def test_the_tools_check_names_the_line_and_module_of_a_private_import(tmp_path: Path) -> None:
    modules = set(module_graph())
    script = tmp_path / "tool.py"
    script.write_text(
        "import sys\nfrom hilrig.cli import main\n\n\ndef f():\n    from hilrig.engine.driver import X\n"
    )
    assert hilrig_imports(script, modules) == [(2, "hilrig.cli"), (6, "hilrig.engine.driver")]
    shell = tmp_path / "tool"
    shell.write_text(
        '#!/usr/bin/env bash\n# hilrig.wire is named here only\nexec python -m hilrig.wire.node "$@"\n'
    )
    assert hilrig_imports(shell, modules) == [(3, "hilrig.wire.node")]
    public = public_modules()
    assert [
        is_public(m, public) for m in ("hilrig.cli", "hilrig.engine.driver", "hilrig.apps.bench.main")
    ] == [
        True,
        False,
        True,
    ]
