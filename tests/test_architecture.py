"""The package's layers (docs/architecture.md): imports point downward only.

Two independent checks: import-linter's contracts in ``.importlinter`` (the layers, and the
three systems independent of each other), and an import graph read here from the source
with every ``import`` statement, including those inside functions, which must have no cycle.
"""

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "flapsim"

#: Packages that may be imported inside a function: optional, or heavy and needed by one path
#: (mpl_toolkits ships with matplotlib: its 3D axes).
LAZY_ALLOWED = {"matplotlib", "mpl_toolkits", "pyvista", "imageio", "ray", "vtk"}


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PACKAGE.rglob("*.py"):
        name = ".".join(p.relative_to(ROOT).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    return mods


def _resolve(name: str, mods: dict[str, Path]) -> str:
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name


def _imports(path: Path):
    """(imported dotted names, is the statement at module level) for every import."""
    tree = ast.parse(path.read_text())
    top = {id(n) for n in tree.body}
    for n in tree.body:  # ``if TYPE_CHECKING:`` / ``try:`` at module level count as top
        if isinstance(n, (ast.If, ast.Try)):
            top |= {id(x) for x in ast.walk(n)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield [a.name for a in node.names], id(node) in top, node.lineno
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield [f"{node.module}.{a.name}" for a in node.names], id(node) in top, node.lineno


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph = {m: set() for m in mods}
    for m, p in mods.items():
        for names, _, _ in _imports(p):
            for n in names:
                if n.startswith("flapsim"):
                    r = _resolve(n, mods)
                    if r and r != m:
                        graph[m].add(r)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
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
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_planted_cycle():
    # the check below must be able to fail: a -> b -> c -> a is one component of three
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(g) == [["a", "b", "c"]]


def test_no_import_cycle_even_through_imports_inside_functions():
    assert _cycles(_graph()) == []


def test_imports_inside_functions_only_for_optional_heavy_packages():
    lazy = []
    for p in _modules().values():
        for names, at_top, line in _imports(p):
            if not at_top and names[0].split(".")[0] not in LAZY_ALLOWED:
                lazy.append(f"{p.relative_to(ROOT)}:{line} {names[0]}")
    assert lazy == []


def test_import_flapsim_sets_no_environment_variable():
    code = ("import os; before = dict(os.environ); import flapsim, flapsim.bird, flapsim.swim, "
            "flapsim.modal; print(sorted(set(os.environ.items()) ^ set(before.items())))")
    env = {k: v for k, v in __import__("os").environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.strip()
    assert out == "[]"


def test_layers_contract_holds():
    # import-linter reads .importlinter: the layers, and bird, swim and modal independent
    code = ("import sys; from importlinter.cli import lint_imports; "
            f"sys.exit(lint_imports(config_filename={str(ROOT / '.importlinter')!r}, no_cache=True))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
