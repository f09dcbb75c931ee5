"""The package's layout: layers, imports and function sizes (docs/design.md, "Package layout").

Read from the source as text (nothing is imported), so a module that breaks a rule fails here
before a reader meets it: an import running back up a layer, a private name imported from another
module, a function over 100 lines, a class over 350 lines or a module over 800 lines outside the
compiled kernels.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "ipromp_pin"

LAYERS = {
    **dict.fromkeys(["data", "exceptions", "atomic", "cache", "inputs", "fields", "shipped", "version"], 0),
    "signals": 1,
    "readers": 2,
    **dict.fromkeys(["promp", "robot", "human", "preview", "schemas"], 3),
    "motion": 4,
    "safety": 5,
    "planning": 6,
    "evaluation": 7,
    "outputs": 8,
    "plans": 9,
    "app": 10,
}
"""Top-level module or package -> layer (0: the shared ground); imports may only go down."""

TOP_LEVEL = {
    "__init__",
    "data",
    "exceptions",
    "atomic",
    "cache",
    "inputs",
    "fields",
    "shipped",
    "version",
}
"""What the package's top level may hold besides packages."""

MAX_FUNCTION_LINES = 100
MAX_CLASS_LINES = 350
MAX_MODULE_LINES = 800
COMPILED_KERNELS = {"promp/_kernels.py"}

KNOWN_LONG: set[str] = set()
"""Modules allowed over the class or module limit, outside the compiled kernels (none)."""


def _modules() -> list[tuple[str, Path, ast.Module]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out.append((".".join(parts), path, ast.parse(path.read_text(encoding="utf-8"))))
    return out


def _imports(module: str, path: Path, tree: ast.Module) -> list[tuple[str, list[str], int]]:
    """(imported module, imported names, line) of every import of the package's own modules."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base) + (f".{node.module}" if node.module else "")
            else:
                target = node.module or ""
            names = [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            target, names = "", [a.name for a in node.names]
            for name in names:
                if name.startswith("ipromp_pin"):
                    found.append((name, [], node.lineno))
            continue
        else:
            continue
        if target.startswith("ipromp_pin"):
            found.append((target, names, node.lineno))
    return found


def _top(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_the_top_level_holds_only_the_shared_ground_and_packages():
    flat = {p.stem for p in PACKAGE.glob("*.py")}
    assert flat <= TOP_LEVEL, f"modules beside the packages: {sorted(flat - TOP_LEVEL)}"
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    assert packages <= set(LAYERS), f"packages without a layer: {sorted(packages - set(LAYERS))}"


def test_imports_only_go_down_the_layers():
    up = []
    for module, path, tree in _modules():
        src = _top(module)
        if src is None:  # the package's own __init__: the public API, above everything
            continue
        for target, names, line in _imports(module, path, tree):
            targets = [f"{target}.{n}" for n in names] if target == "ipromp_pin" else [target]
            for t in targets:
                dst = _top(t)
                if dst is not None and dst != src and dst in LAYERS and LAYERS[dst] > LAYERS[src]:
                    up.append(f"{path.relative_to(PACKAGE)}:{line} imports {t}")
    assert not up, "imports running up a layer:\n" + "\n".join(up)


def test_no_private_name_is_imported_from_another_module():
    private = []
    for module, path, tree in _modules():
        for target, names, line in _imports(module, path, tree):
            hidden = [n for n in names if n.startswith("_") and not n.startswith("__")]
            hidden += [p for p in target.split(".") if p.startswith("_") and not p.startswith("__")]
            # the compiled kernels are loaded on first use by their own package's dispatcher
            hidden = [n for n in hidden if n != "_kernels"]
            if hidden:
                private.append(f"{path.relative_to(PACKAGE)}:{line} imports {hidden} from {target}")
    assert not private, "private names imported across modules:\n" + "\n".join(private)


def test_no_import_circle_between_packages():
    edges: dict[str, set[str]] = {}
    for module, path, tree in _modules():
        src = _top(module)
        if src is None:
            continue
        for target, _, _ in _imports(module, path, tree):
            dst = _top(target)
            if dst is not None and dst != src:
                edges.setdefault(src, set()).add(dst)

    def reaches(a: str, b: str, seen: set[str]) -> bool:
        return any(n == b or (n not in seen and reaches(n, b, seen | {n})) for n in edges.get(a, ()))

    circles = sorted(f"{a} <-> {b}" for a in edges for b in edges[a] if reaches(b, a, {b}))
    assert not circles, f"packages importing each other: {circles}"


def test_no_function_over_100_lines():
    long = []
    for _, path, tree in _modules():
        if str(path.relative_to(PACKAGE)) in COMPILED_KERNELS:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name} ({n} lines)")
    assert not long, "functions over 100 lines:\n" + "\n".join(long)


def test_no_class_over_350_lines_and_no_module_over_800_lines():
    long = []
    for _, path, tree in _modules():
        name = str(path.relative_to(PACKAGE).as_posix())
        if name in COMPILED_KERNELS or name in KNOWN_LONG:
            continue
        n_lines = len(path.read_text(encoding="utf-8").splitlines())
        if n_lines > MAX_MODULE_LINES:
            long.append(f"{name}: module of {n_lines} lines")
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_CLASS_LINES:
                    long.append(f"{name}:{node.lineno} class {node.name} ({n} lines)")
    assert not long, "over the size limits:\n" + "\n".join(long)


def test_every_known_long_module_is_still_over_a_limit():
    # an entry of KNOWN_LONG for a module that was split would let it grow back unnoticed: remove it
    stale = []
    for name in KNOWN_LONG:
        path = PACKAGE / name
        if not path.is_file():
            stale.append(f"{name} (no such module)")
            continue
        text = path.read_text(encoding="utf-8")
        classes = [n for n in ast.walk(ast.parse(text)) if isinstance(n, ast.ClassDef)]
        longest = max((n.end_lineno - n.lineno + 1 for n in classes), default=0)
        if len(text.splitlines()) <= MAX_MODULE_LINES and longest <= MAX_CLASS_LINES:
            stale.append(f"{name} (within the limits now)")
    assert not stale, f"remove from KNOWN_LONG: {stale}"
