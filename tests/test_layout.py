"""The package's shape, as its modules' source says it: small modules, no
private name imported across modules, no import circle, and a
function-local import only where it defers a heavy library."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "nrdepth"
MAX_LINES = 500
HEAVY = {"torch", "cv2", "plotly", "matplotlib", "scipy", "av", "h5py", "clarabel", "threadpoolctl", "safetensors", "tqdm", "selenium", "ray", "mitsuba", "PIL"}
"""Libraries whose import costs enough that a module may defer it to the function that needs it."""


def modules() -> dict:
    """Dotted name → (path, parsed source) of every module of the package."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = (path, ast.parse(path.read_text(), str(path)))
    return found


MODULES = modules()


def resolve(module: str, node: ast.ImportFrom) -> str:
    """The absolute name a ``from … import`` in ``module`` imports from."""
    if node.level == 0:
        return node.module or ""
    is_package = MODULES[module][0].name == "__init__.py"
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(module: str, top_level: bool) -> list:
    """(node, imported module names) of ``module``'s imports at its top level, or inside functions."""
    tree = MODULES[module][1]
    nodes = tree.body if top_level else [n for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) for n in ast.walk(f)]
    found = []
    for node in nodes:
        if isinstance(node, ast.Import):
            found.append((node, [a.name for a in node.names]))
        elif isinstance(node, ast.ImportFrom):
            base = resolve(module, node)
            # "from package import module" imports the module too.
            found.append((node, [base] + [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES]))
        elif top_level and isinstance(node, ast.If):  # TYPE_CHECKING blocks run at no time
            continue
    return found


def internal_graph() -> dict:
    """Each module → the package's modules its top level imports (a package's __init__ included)."""
    graph = {}
    for module in MODULES:
        targets = set()
        for _, names in imports(module, top_level=True):
            for name in names:
                if name in MODULES and name != module:
                    targets.add(name)
                    parts = name.split(".")  # importing a.b.c runs a/__init__ and a/b/__init__ first
                    targets.update(".".join(parts[:k]) for k in range(2, len(parts)))
        # A module's own packages are always initialised before it: importing from them closes no circle.
        graph[module] = {t for t in targets if t != module and not module.startswith(t + ".")}
    return graph


def test_no_module_is_over_500_lines():
    long = {m: n for m, (path, _) in MODULES.items() if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert not long, f"over {MAX_LINES} lines: {long}"


def test_no_private_name_is_imported_across_modules():
    crossing = []
    for module in MODULES:
        for top_level in (True, False):
            for node, _ in imports(module, top_level):
                if isinstance(node, ast.ImportFrom) and node.level > 0:
                    crossing += [f"{module}: {a.name}" for a in node.names if a.name.startswith("_") and not a.name.endswith("__") and a.name != "_core"]
    assert not crossing, crossing


def test_no_import_circle():
    graph = internal_graph()
    state: dict = {}
    stack: list = []

    def visit(module: str) -> None:
        state[module] = "open"
        stack.append(module)
        for target in sorted(graph[module]):
            if state.get(target) == "open":
                pytest.fail("import circle: " + " → ".join(stack[stack.index(target):] + [target]))
            if target not in state:
                visit(target)
        stack.pop()
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module)


def heavy_at_top(module: str, seen: set) -> bool:
    """Whether importing ``module`` (a name inside or outside the package) imports a heavy library."""
    if module.split(".")[0] in HEAVY:
        return True
    if module not in MODULES or module in seen:
        return False
    seen.add(module)
    parts = module.split(".")
    parents = [".".join(parts[:k]) for k in range(2, len(parts))]
    return any(heavy_at_top(name, seen) for _, names in imports(module, top_level=True) for name in names) or any(
        heavy_at_top(p, seen) for p in parents)


def test_function_local_imports_defer_a_heavy_library():
    """A function-local import is there to keep ``import nrdepth`` light,
    never to hide a circle: what it imports must pull in a heavy library."""
    light = []
    for module in MODULES:
        for node, names in imports(module, top_level=False):
            if not any(heavy_at_top(name, set()) for name in names):
                light.append(f"{module}:{node.lineno} imports {names[0]}")
    assert not light, light


def test_import_nrdepth_leaves_torch_out():
    import subprocess
    import sys

    code = "import sys, nrdepth; print(sorted(m for m in ('torch', 'cv2', 'plotly', 'matplotlib', 'scipy') if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]", result.stdout
