"""The package's largest modules, functions and classes by line count (read with ast).

    python scripts/code_size.py [--top N]

A function's lines run from its `def` (decorators excluded) to its last line, docstring and
nested functions included: the size a reader has to hold at once. tests/test_layout.py uses
`sizes` to keep every function of the package under FUNCTION_LIMIT lines.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "dfeif_codegen"


def _defs(tree: ast.AST, kinds: tuple) -> list:
    return [n for n in ast.walk(tree) if isinstance(n, kinds)]


def sizes(package: Path = PACKAGE) -> tuple[list, list, list]:
    """(lines, module) and (lines, qualified name) of functions and of classes, largest first."""
    modules, functions, classes = [], [], []
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package.parent).as_posix()
        text = path.read_text(encoding="utf-8")
        modules.append((len(text.splitlines()), rel))
        tree = ast.parse(text)
        for node in _defs(tree, (ast.FunctionDef, ast.AsyncFunctionDef)):
            functions.append((node.end_lineno - node.lineno + 1, f"{rel}:{node.lineno} {node.name}"))
        for node in _defs(tree, (ast.ClassDef,)):
            classes.append((node.end_lineno - node.lineno + 1, f"{rel}:{node.lineno} {node.name}"))
    return (sorted(modules, reverse=True), sorted(functions, reverse=True), sorted(classes, reverse=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=5)
    top = ap.parse_args().top
    for title, rows in zip(("modules", "functions", "classes"), sizes()):
        print(f"largest {title}:")
        for lines, name in rows[:top]:
            print(f"  {lines:5d}  {name}")


if __name__ == "__main__":
    main()
