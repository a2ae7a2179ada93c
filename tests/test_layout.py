"""Dependencies point one way, model -> flat system -> kernels -> C -> compared: each stage of the
package imports only the stages before it (read from the import statements, not from a list)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "dfeif_codegen"
BASE = {"errors", "constants", "__version__", "budget", "paths"}   # leaf utilities every stage may use
ALLOWED = {
    "errors": set(), "constants": set(), "budget": {"errors"}, "paths": {"errors"},
    "symbolic": BASE,
    "codegen": BASE | {"symbolic"},                      # the generator never sees the reference
    "reference": BASE | {"symbolic"},
    "experiment": BASE | {"symbolic", "reference"},
    "check": BASE | {"symbolic", "codegen", "reference", "experiment"},
    "net": BASE | {"symbolic", "codegen", "reference", "experiment", "check"},   # programs on a network
    "cli": BASE | {"symbolic", "codegen", "reference", "experiment", "check", "net"},
    "__init__": BASE,
}
# The one known exception, kept visible: the sweep runs each closed loop on the engine the user
# picks, and the compiled engine lives in check/ (it compiles C). It is imported inside the worker
# function only, so importing experiment/ never loads check/.
EXCEPTIONS = {"experiment/sweep.py": {"check"}}


def imported_stages(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "dfeif_codegen":
            parts = node.module.split(".")
            out |= {parts[1]} if len(parts) > 1 else {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("dfeif_codegen.")}
    return out


def test_each_stage_imports_only_earlier_stages():
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).parts
        stage = parts[0] if len(parts) > 1 else path.stem
        if stage in ("models", "templates"):
            continue
        extra = imported_stages(path) - ALLOWED[stage] - {stage} \
            - EXCEPTIONS.get(str(path.relative_to(PACKAGE)), set())
        if extra:
            bad.append(f"{path.relative_to(PACKAGE)} imports {sorted(extra)}")
    assert bad == []
