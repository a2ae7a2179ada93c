"""dfeif-codegen: symbolic flat robot models to verified embedded C for distributed
derivative-free Kalman filtering under packet drops and variable delays.

The public API, in the order data flows:

    model = load_model("dc_motor_link")   # symbolic model (a built-in name, a .toml path)
    flat = derive(model)                  # flatness transform, canonical form, discretization
    module = build(model, "out")          # CasADi kernels + templates -> out/<model>/
    lib = load(module)                    # compiled with the host compiler, loaded with ctypes
    node = lib.Node(x0, P0, R, q)         # the generated C as Python objects (see README)
    result = simulate(runs=5)             # the chapter's experiment: result.tables, .report()

Every command's function takes the command's options as keywords, in the same units, and
returns data (`verify`, `simulate`, `bench`, `network`: result objects with `.report()`, the
text the command prints, and `.to_json()`). Errors are exceptions exported here: CodegenError
and its family (bad input, exit 2 in the CLI), CError and one subclass per C return code.

Names are imported on first use, so `codegen --version` does not load sympy and CasADi; the
imports under TYPE_CHECKING give type checkers the same names (tests/test_public_api.py keeps
the two lists equal).
"""

from typing import TYPE_CHECKING

__version__ = "0.1.0"

_API = {
    "load_model": ("dfeif_codegen.symbolic.model", "load"),
    "from_sympy": ("dfeif_codegen.symbolic.model", "from_sympy"),
    "derive": ("dfeif_codegen.symbolic.flatness", "derive"),
    "build": ("dfeif_codegen.codegen.build", "build"),
    "check_build": ("dfeif_codegen.codegen.build", "check"),
    "load": ("dfeif_codegen.check.loader", "load"),
    "inspect": ("dfeif_codegen.symbolic.inspect_model", "inspect"),
    "verify": ("dfeif_codegen.check.verify", "verify"),
    "bench": ("dfeif_codegen.check.bench", "bench"),
    "simulate": ("dfeif_codegen.api", "simulate"),
    "scenario": ("dfeif_codegen.experiment.starter", "scenario"),
    "network": ("dfeif_codegen.net.run", "network"),
    "reproduce": ("dfeif_codegen.reproduction.run", "reproduce"),
    # errors the user can fix (the CLI: one line, exit 2; MismatchError exit 1)
    "CodegenError": ("dfeif_codegen.errors", "CodegenError"),
    "ModelError": ("dfeif_codegen.errors", "ModelError"),
    "ScenarioError": ("dfeif_codegen.errors", "ScenarioError"),
    "SetupError": ("dfeif_codegen.errors", "SetupError"),
    "MismatchError": ("dfeif_codegen.errors", "MismatchError"),
    "BuildError": ("dfeif_codegen.codegen.options", "BuildError"),
    "BudgetError": ("dfeif_codegen.budget", "BudgetError"),
    "OutputPathError": ("dfeif_codegen.paths", "OutputPathError"),
    # a generated C function's return code (dc.load)
    "CError": ("dfeif_codegen.check.loader", "CError"),
    "ArgError": ("dfeif_codegen.check.loader", "ArgError"),
    "LagError": ("dfeif_codegen.check.loader", "LagError"),
    "NonFiniteError": ("dfeif_codegen.check.loader", "NonFiniteError"),
    "SingularError": ("dfeif_codegen.check.loader", "SingularError"),
    "DuplicateError": ("dfeif_codegen.check.loader", "DuplicateError"),
    "SequenceError": ("dfeif_codegen.check.loader", "SequenceError"),
    "OutlierError": ("dfeif_codegen.check.loader", "OutlierError"),
}

__all__ = ["__version__", *_API]

if TYPE_CHECKING:  # never run: the names above for type checkers, without loading anything
    from dfeif_codegen.api import simulate
    from dfeif_codegen.budget import BudgetError
    from dfeif_codegen.check.bench import bench
    from dfeif_codegen.check.loader import (ArgError, CError, DuplicateError, LagError, NonFiniteError,
                                            OutlierError, SequenceError, SingularError, load)
    from dfeif_codegen.check.verify import verify
    from dfeif_codegen.codegen.build import build
    from dfeif_codegen.codegen.build import check as check_build
    from dfeif_codegen.codegen.options import BuildError
    from dfeif_codegen.errors import CodegenError, MismatchError, ModelError, ScenarioError, SetupError
    from dfeif_codegen.experiment.starter import scenario
    from dfeif_codegen.net.run import network
    from dfeif_codegen.paths import OutputPathError
    from dfeif_codegen.reproduction.run import reproduce
    from dfeif_codegen.symbolic.flatness import derive
    from dfeif_codegen.symbolic.inspect_model import inspect
    from dfeif_codegen.symbolic.model import from_sympy
    from dfeif_codegen.symbolic.model import load as load_model


def __getattr__(name: str) -> object:
    if name in _API:
        import importlib

        module, attr = _API[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dfeif_codegen' has no attribute {name!r}")
