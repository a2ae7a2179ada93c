"""Dependencies point one way, model -> flat system -> kernels -> C -> compared, read from the
import statements of every module (module level and inside functions alike, since a function's
import runs as surely as a module's, only later): no import cycle between modules, no module
importing a later stage, and each stage importing only the stages it needs."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "dfeif_codegen"

# README "Layout", in order. Stage 0 holds the leaf utilities every stage may use: the error
# classes, the shared numbers, the angle wrap the kernels and the reference share (angles.py),
# the output-path checks (paths.py: symbolic/ checks a model file
# path with it) and the time/memory budget of a child process (budget.py: the symbolic
# derivation runs under it), the strict JSON writer (json_text.py: simulate, verify and network
# write it), and the package root, which imports nothing (its names load lazily
# by name). The Python face of the commands (api.py, __main__.py) sits with the CLI.
STAGES = [
    {"__init__", "errors", "constants", "angles", "paths", "budget", "json_text"},
    {"symbolic"}, {"models"}, {"codegen"}, {"reference"}, {"experiment"}, {"check"}, {"net"},
    {"api", "reproduction", "cli", "__main__"},
]
RANK = {name: i for i, names in enumerate(STAGES) for name in names}
BASE = STAGES[0]
# Stricter than the order: the generator never sees the reference, nor the experiment the generator.
ALLOWED = {
    "symbolic": BASE,
    "codegen": BASE | {"symbolic"},
    "reference": BASE | {"symbolic"},
    "experiment": BASE | {"symbolic", "reference"},
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _runnable(tree: ast.AST):
    """Every node except the bodies of `if TYPE_CHECKING:`, which never run (the package root
    names its lazily loaded API there for type checkers)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            todo.extend(node.orelse)
            continue
        todo.extend(ast.iter_child_nodes(node))


def imports(path: Path, known: set[str]) -> list[tuple[str, int]]:
    here = module_name(path)
    return imports_in(path.read_text(encoding="utf-8"), here if path.name == "__init__.py" else here.rsplit(".", 1)[0],
                      known)


def imports_in(text: str, package: str, known: set[str]) -> list[tuple[str, int]]:
    """(module of the package, line) for every import statement of a module of `package`,
    wherever it stands; `from pkg import name` counts as importing pkg.name when that is a module."""
    out = []
    for node in _runnable(ast.parse(text)):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names if a.name.split(".")[0] == "dfeif_codegen"]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:   # relative: resolved against this module's package
                up = package.split(".")
                base = ".".join(up[:len(up) - node.level + 1] + ([base] if base else []))
            if base.split(".")[0] != "dfeif_codegen":
                continue
            for a in node.names:
                full = f"{base}.{a.name}"
                out.append((full if full in known else base, node.lineno))
    return out


def graph() -> dict[str, list[tuple[str, int]]]:
    mods = modules()
    return {name: imports(path, set(mods)) for name, path in mods.items()}


def stage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def cycles(edges: dict[str, list[tuple[str, int]]]) -> list[list[str]]:
    """Every strongly connected component with more than one module, or a module importing itself
    (Tarjan's algorithm, iterative)."""
    index, low, on, stack, found, counter = {}, {}, set(), [], [], [0]
    succ = {m: sorted({t for t, _ in e if t in edges}) for m, e in edges.items()}

    def visit(root):
        work = [(root, iter(succ[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            node, it = work[-1]
            nxt = next(it, None)
            if nxt is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        m = stack.pop()
                        on.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    if len(comp) > 1 or node in succ[node]:
                        found.append(sorted(comp))
            elif nxt not in index:
                index[nxt] = low[nxt] = counter[0]
                counter[0] += 1
                stack.append(nxt)
                on.add(nxt)
                work.append((nxt, iter(succ[nxt])))
            elif nxt in on:
                low[node] = min(low[node], index[nxt])

    for m in sorted(succ):
        if m not in index:
            visit(m)
    return found


def test_every_module_belongs_to_a_stage():
    assert {stage(m) for m in modules()} <= set(RANK)


def test_no_import_cycle_between_modules():
    assert cycles(graph()) == []


def test_no_module_imports_a_later_stage():
    bad = [f"{src} (line {line}) imports {dst}" for src, edges in graph().items() for dst, line in edges
           if RANK[stage(dst)] > RANK[stage(src)]]
    assert bad == []


def test_early_stages_import_only_what_they_need():
    bad = [f"{src} (line {line}) imports {dst}" for src, edges in graph().items() for dst, line in edges
           if stage(src) in ALLOWED and stage(dst) not in ALLOWED[stage(src)] | {stage(src)}]
    assert bad == []


def test_the_checks_find_a_cycle_and_an_upward_import():
    """The checker itself, on a made-up graph: a -> b -> c -> a is one cycle, d alone is none,
    e importing itself is one; an experiment module importing check is upward."""
    edges = {"a": [("b", 1)], "b": [("c", 1)], "c": [("a", 1)], "d": [("a", 1)], "e": [("e", 1)]}
    assert cycles(edges) == [["a", "b", "c"], ["e"]]
    assert RANK[stage("dfeif_codegen.check.harness")] > RANK[stage("dfeif_codegen.experiment.sweep")]


def test_imports_are_read_inside_functions_and_outside_type_checking():
    text = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from dfeif_codegen.net import run\n"
            "def f():\n    from dfeif_codegen.check import harness\n    from . import plan\n")
    found = imports_in(text, "dfeif_codegen.experiment", {"dfeif_codegen.check.harness", "dfeif_codegen.experiment.plan"})
    assert sorted(found) == [("dfeif_codegen.check.harness", 5), ("dfeif_codegen.experiment.plan", 6)]


# Functions longer than a reader holds at once; an exception would be listed here with the change
# that removes it.
FUNCTION_LIMIT = 80
LONG_FUNCTIONS: dict[str, str] = {}


def test_no_function_is_longer_than_the_limit():
    """scripts/code_size.py measures a function from its `def` to its last line."""
    import sys
    sys.path.insert(0, str(PACKAGE.parent / "scripts"))
    import code_size

    _, functions, _ = code_size.sizes(PACKAGE)
    long = {f"{where.split(':')[0]} {where.split()[-1]}": lines for lines, where in functions if lines > FUNCTION_LIMIT}
    assert set(long) - set(LONG_FUNCTIONS) == set(), long
    assert set(LONG_FUNCTIONS) - set(long) == set(), "remove the exceptions that no longer hold"


# One module per concept and classes a reader can hold: a module past MODULE_LIMIT lines or a
# class past CLASS_LIMIT is split by concept (README "Layout"), not given an exception.
MODULE_LIMIT = 400
CLASS_LIMIT = 200


def test_no_module_or_class_is_longer_than_the_limit():
    import sys
    sys.path.insert(0, str(PACKAGE.parent / "scripts"))
    import code_size

    modules, _, classes = code_size.sizes(PACKAGE)
    assert [(lines, name) for lines, name in modules if lines > MODULE_LIMIT] == []
    assert [(lines, name) for lines, name in classes if lines > CLASS_LIMIT] == []
