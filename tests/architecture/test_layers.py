"""The package's layers (docs/architecture.md): every import of a cufund module, at the top of a file or inside a
function, by a statement or by ``importlib.import_module("cufund...")``, goes to the module's own area or to a
lower layer, and no modules import each other in a circle.

The imports are read with ``ast`` from the source files, so a lazy import inside a function counts as much as one
at the top of a file."""

from __future__ import annotations

import ast
from pathlib import Path

import cufund

ROOT = Path(cufund.__file__).resolve().parent

LAYERS: list[tuple[str, ...]] = [
    ("_core",),
    ("core",),
    ("geometry",),
    ("vehicle", "worlds", "logs"),
    ("simulator",),
    ("sensors",),
    ("estimation", "mapping", "perception"),
    ("planning",),
    ("control",),
    ("viz",),
    ("missions",),
    ("scenarios",),
    ("envs",),
    ("apps",),
    ("__init__",),
    ("templates",),
]
"""Bottom to top; the areas on one line are peers and may not import each other. ``__init__`` is the public API
(``import cufund``); ``templates`` are examples of user code, written against that API as a user would."""
RANK = {area: i for i, areas in enumerate(LAYERS) for area in areas}


def _modules() -> dict[str, tuple[Path, bool]]:
    out = {}
    for f in ROOT.rglob("*.py"):
        rel = f.relative_to(ROOT.parent).with_suffix("")
        parts = list(rel.parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        out[".".join(parts)] = (f, is_pkg)
    return out


MODULES = _modules()
MODULES["cufund._core"] = (ROOT / "_core", True)  # the compiled extension (its stubs are in _core/)


def _area(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "__init__"
    return parts[1]


def _resolve(name: str) -> str:
    """The module ``name`` names: itself if it is a module, else the module that defines the attribute."""
    if name == "cufund._core" or name.startswith("cufund._core."):
        return "cufund._core"
    while name not in MODULES and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def _imports(module: str) -> list[tuple[str, int]]:
    path, is_pkg = MODULES[module]
    package = module if is_pkg else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(_resolve(a.name), node.lineno) for a in node.names if a.name.split(".")[0] == "cufund"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "cufund":
                continue
            for a in node.names:  # `from pkg import submodule` imports the submodule
                found.append((_resolve(f"{target}.{a.name}"), node.lineno))
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            # importlib.import_module("cufund.x") and __import__("cufund.x") import as much as a statement does
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
            value = node.args[0].value
            if name in ("import_module", "__import__") and isinstance(value, str) and value.split(".")[0] == "cufund":
                found.append((_resolve(value), node.lineno))
    return [(t, line) for t, line in found if t != module]


GRAPH = {m: _imports(m) for m in MODULES if m != "cufund._core"}
GRAPH["cufund._core"] = []


def test_every_area_has_a_layer():
    areas = {_area(m) for m in MODULES}
    assert areas <= set(RANK), f"areas without a layer in docs/architecture.md: {sorted(areas - set(RANK))}"


def test_imports_only_go_down():
    upward = []
    for module, imports in GRAPH.items():
        area = _area(module)
        for target, line in imports:
            t_area = _area(target)
            if t_area != area and RANK[t_area] >= RANK[area]:
                upward.append(
                    f"{MODULES[module][0].relative_to(ROOT.parent)}:{line} {module} ({area}, layer "
                    f"{RANK[area]}) imports {target} ({t_area}, layer {RANK[t_area]})"
                )
    assert not upward, "imports that do not go down a layer:\n" + "\n".join(sorted(upward))


def _package_of(module: str) -> str | None:
    return module.rsplit(".", 1)[0] if "." in module else None


def test_no_import_circle():
    """No module reaches itself through imports (a package's ``__init__`` importing its own submodules, and a
    submodule importing a sibling through the package, are the normal shape of a package and not counted)."""

    def edges(m: str) -> list[str]:
        out = []
        for t, _ in GRAPH[m]:
            if MODULES[t][1] and (m.startswith(t + ".")):
                continue  # a module inside package t imports t's __init__ (re-exported names)
            out.append(t)
        return out

    state: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in edges(m):
            if state.get(t) == 1:
                circles.append(stack[stack.index(t) :] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m)
    assert not circles, "import circles:\n" + "\n".join(" -> ".join(c) for c in circles)


def test_the_checker_sees_an_upward_import(tmp_path):
    """The walk finds what it is for: a planted upward import and a planted circle."""
    global GRAPH
    saved = dict(GRAPH)
    try:
        GRAPH["cufund.core.bus"] = saved["cufund.core.bus"] + [("cufund.apps.cli", 1)]
        try:
            test_imports_only_go_down()
        except AssertionError as e:
            assert "cufund.core.bus (core, layer 1) imports cufund.apps.cli" in str(e)
        else:
            raise AssertionError("the planted upward import was not found")
        fake = tmp_path / "fake.py"
        fake.write_text('import importlib\n\ndef f():\n    return importlib.import_module("cufund.planning.kinds")\n')
        MODULES["cufund.logs.fake"] = (fake, False)
        try:
            assert ("cufund.planning.kinds", 4) in _imports("cufund.logs.fake")
        finally:
            del MODULES["cufund.logs.fake"]
        GRAPH = dict(saved)
        GRAPH["cufund.core.topics"] = saved["cufund.core.topics"] + [("cufund.core.bus", 1)]
        try:
            test_no_import_circle()
        except AssertionError as e:
            assert "cufund.core.bus" in str(e) and "cufund.core.topics" in str(e)
        else:
            raise AssertionError("the planted circle was not found")
    finally:
        GRAPH = saved
