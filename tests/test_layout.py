"""The package layout: one subpackage per pipeline stage, imports pointing one way, modules a
reader can follow."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "strokekit"
CLI = PKG.parent / "cli"

#: Stages in pipeline order. A stage may import the shared top-level modules and the stages
#: before it, never one after it; writers and metrics read what the stages make.
STAGES = ("camera", "scene", "lines", "tracking", "paths", "raster", "style", "ribbons", "writers", "metrics", "run")
#: What each stage may import besides the top-level modules.
ALLOWED = {
    "camera": set(),
    "scene": {"camera"},
    "lines": {"scene", "camera"},
    "tracking": {"camera", "lines"},
    "paths": {"camera", "lines", "tracking"},
    "raster": {"scene", "camera"},
    "style": {"camera"},
    "ribbons": {"camera", "style"},
    "writers": {"camera", "ribbons", "style"},
    "metrics": {"scene", "camera", "lines", "raster", "style", "writers"},
    "run": {"scene", "camera", "lines", "tracking", "paths", "raster", "style", "ribbons", "writers"},
}
#: Function-level imports allowed: optional or heavy backends loaded only when used (trimesh:
#: the mesh parser, skipped when the scene cache answers; open3d: its plotly part is stubbed out
#: first with sys and types).
LAZY_OK = {"trimesh", "sys", "types", "open3d", "embreex", "matplotlib", "PIL", "psutil", "pygltflib", "dask", "distributed", "numba",
           "OpenEXR", "Imath", "shapely", "rtree", "scipy", "multiprocessing", "signal", "importlib"}


def _module(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(p) for p in PKG.rglob("*.py")}


def _imports() -> tuple[dict[str, set[str]], list[tuple[str, int, str]]]:
    """({module: strokekit modules it imports at import time}, [(module, line, name) of imports inside functions])."""
    graph: dict[str, set[str]] = defaultdict(set)
    inner = []
    for path in sorted(PKG.rglob("*.py")):
        mod = _module(path)
        tree = ast.parse(path.read_text())
        # module level: the body, and imports in its try/except blocks (alternative backends);
        # imports under `if TYPE_CHECKING:` are for annotations and run nothing
        top = {id(n) for n in tree.body}
        top |= {id(b) for n in tree.body if isinstance(n, ast.Try) for b in ast.walk(n)}
        typing_only = {id(b) for n in tree.body if isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test)
                       for b in ast.walk(n)}
        graph[mod]
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and "." in node.value \
                    and node.value in MODULES:
                # a module imported by name (importlib.import_module: numba's kernels, loaded only
                # when a raster pass runs) is an arrow like any import
                graph[mod].add(node.value)
                continue
            if isinstance(node, ast.ImportFrom):
                name = node.module or ""
                if node.level:
                    raise AssertionError(f"{mod}: relative import (the package imports by absolute names)")
            elif isinstance(node, ast.Import):
                name = node.names[0].name
            else:
                continue
            if id(node) in typing_only:
                continue
            if id(node) not in top:
                inner.append((mod, node.lineno, name))
            if name.startswith("strokekit") and id(node) in top:
                graph[mod].add(name)
                # importing a.b.c runs a.b's __init__ too (but a module's own package is already
                # initialized by the time the module runs)
                parts = name.split(".")
                graph[mod].update(".".join(parts[:k]) for k in range(2, len(parts))
                                  if not mod.startswith(".".join(parts[:k]) + "."))
        graph[mod].discard(mod)
    return graph, inner


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(v: str) -> list[str] | None:
        state[v] = 1
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if state.get(w) == 1:
                return stack[stack.index(w):] + [w]
            if w in graph and w not in state:
                found = visit(w)
                if found:
                    return found
        stack.pop()
        state[v] = 2
        return None

    for v in sorted(graph):
        if v not in state:
            found = visit(v)
            if found:
                return found
    return None


def test_cycle_finder_finds_a_cycle():
    """The check below can fail: a three-module loop is reported."""
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_no_import_cycle_among_the_package_modules():
    graph, _ = _imports()
    assert _cycle(graph) is None
    # (modules imported by name count: the raster pass's compiled kernels)
    assert {"strokekit.raster.zbuffer", "strokekit.raster.compiled"} <= graph["strokekit.raster.hits"]


def test_stages_import_only_earlier_stages():
    """Arrows point one way: no stage imports a writer or a metric, writers and metrics read the model."""
    graph, _ = _imports()
    wrong = []
    for mod, targets in graph.items():
        parts = mod.split(".")
        if len(parts) < 3 and not (len(parts) == 2 and parts[1] in STAGES):
            continue  # top-level shared modules are checked below
        stage = parts[1]
        for t in targets:
            tp = t.split(".")
            if len(tp) >= 2 and tp[1] in STAGES and tp[1] != stage and tp[1] not in ALLOWED[stage]:
                wrong.append(f"{mod} imports {t}")
    assert not wrong, "\n".join(sorted(wrong))


def test_shared_top_level_modules_import_no_stage():
    graph, _ = _imports()
    wrong = [f"{m} imports {t}" for m, ts in graph.items() if m.count(".") == 1 and m.split(".")[1] not in STAGES
             for t in ts if t.count(".") >= 1 and t.split(".")[1] in STAGES and m != "strokekit"]
    assert not wrong, "\n".join(sorted(wrong))


def test_imports_inside_functions_are_only_optional_backends():
    _, inner = _imports()
    wrong = [f"{m}:{line} imports {name}" for m, line, name in inner if name.split(".")[0] not in LAZY_OK]
    assert not wrong, "\n".join(wrong)


def _private_imports(paths) -> list[str]:
    """'module:line imports name' for each import of another module's private name (one leading
    underscore): `from m import _x`, or `m._x` on a module imported as `m`."""
    wrong = []
    for path in paths:
        tree = ast.parse(path.read_text())
        modules = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
                   if a.name.startswith("strokekit")}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                wrong += [f"{path.name}:{node.lineno} imports {node.module}.{a.name}" for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules \
                    and node.attr.startswith("_") and not node.attr.startswith("__"):
                wrong.append(f"{path.name}:{node.lineno} uses {node.value.id}.{node.attr}")
    return wrong


def test_the_private_import_finder_finds_them(tmp_path):
    (tmp_path / "a.py").write_text("from strokekit.run.tasks import _write, frame_task\nimport strokekit.run.tasks as T\n"
                                   "T._write\nfrom x import __version__\n")
    assert _private_imports([tmp_path / "a.py"]) == ["a.py:1 imports strokekit.run.tasks._write", "a.py:3 uses T._write"]


def test_no_module_imports_a_private_name_of_another():
    """A name with a leading underscore belongs to its module: what another module needs is made
    public (or moved where both can reach it), so that a module can change its own helpers."""
    wrong = _private_imports(sorted([*PKG.rglob("*.py"), *CLI.rglob("*.py")]))
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize("stage", STAGES)
def test_each_stage_is_a_subpackage_with_a_public_entry_point(stage):
    init = PKG / stage / "__init__.py"
    assert init.exists()
    tree = ast.parse(init.read_text())
    assert ast.get_docstring(tree), f"{stage}/__init__.py says what the stage does"
    names = [n for n in tree.body if isinstance(n, ast.Assign) and any(
        isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets)]
    assert names, f"{stage}/__init__.py lists its public names in __all__"


#: The longest a module may be: past it, a reader no longer finds the algorithm it holds.
MAX_MODULE_LINES = 1200


def test_no_module_is_longer_than_a_reader_can_follow():
    long = {str(p.relative_to(PKG.parent)): n for p in sorted(PKG.rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"
