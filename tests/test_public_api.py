"""The public API as a user meets it: the names at `dc.*` (functions and exceptions), typed for
their type checker (mypy on the API surface, py.typed shipped), the same keywords and units as
the command line, and `python -m dfeif_codegen`."""

from __future__ import annotations

import ast
import inspect
import os
import subprocess
import sys
from pathlib import Path

import pytest

import dfeif_codegen as dc
from conftest import require_module
from dfeif_codegen import cli

ROOT = Path(__file__).resolve().parents[1]


def _mypy(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    require_module("mypy")
    # MYPYPATH: the package from this checkout (mypy cannot follow an editable install's import hook)
    env = {**os.environ, "MYPYPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"), *args],
                          cwd=cwd, capture_output=True, text=True, timeout=600, env=env)


def test_mypy_passes_on_the_public_api(tmp_path):
    """pyproject.toml's [tool.mypy] lists the package root and the modules whose names it exports."""
    proc = _mypy("--cache-dir", str(tmp_path / "cache"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    listed = {Path(f).as_posix() for f in _mypy_files()}
    exported = {"dfeif_codegen/" + module.split(".", 1)[1].replace(".", "/") + ".py"
                for module, _ in dc._API.values()}
    assert exported <= listed


def _mypy_files() -> list[str]:
    import re
    text = (ROOT / "pyproject.toml").read_text()
    block = re.search(r"\[tool\.mypy\].*?files = \[(.*?)\]", text, re.S)
    assert block
    return re.findall(r'"([^"]+)"', block.group(1))


def test_a_users_code_is_checked_against_the_real_signatures(tmp_path):
    """mypy sees the API's own types through the lazy root (not Any): a correct use passes, a
    keyword in the wrong type or a misspelt one is reported at its line."""
    good = tmp_path / "good.py"
    good.write_text(
        "import dfeif_codegen as dc\n"
        "from dfeif_codegen.experiment.report import SimulationResult\n"
        "r: SimulationResult = dc.simulate('dc_motor_link', runs=2, engine='reference')\n"
        "rows: list = r.table('sinusoid', 'replay', 'difference').rows\n"
        "m = dc.build('dc_motor_link', 'out', max_memory=2.0, max_seconds=60.0)\n"
        "try:\n    pass\nexcept dc.SequenceError as e:\n    code: int = e.code\n")
    bad = tmp_path / "bad.py"
    bad.write_text("import dfeif_codegen as dc\n"
                   "dc.simulate('dc_motor_link', runs='two')\n"
                   "dc.verify('dc_motor_link', targte='host')\n")
    proc = _mypy("--cache-dir", str(tmp_path / "cache"), "--follow-imports=silent", str(good), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = _mypy("--cache-dir", str(tmp_path / "cache"), "--follow-imports=silent", str(bad), cwd=tmp_path)
    assert "bad.py:2: error" in proc.stdout and "bad.py:3: error" in proc.stdout, proc.stdout


def test_py_typed_ships_in_the_wheel(tmp_path):
    """Built the way a wheel is built (setuptools' build_py, in a copy of the tree): py.typed and
    the API modules are in it; the metadata's MIT licence has its LICENSE file; mypy is in the
    test extra (the test above needs it)."""
    import shutil

    from dfeif_codegen.paths import tomllib   # the standard library's, or its backport on 3.10

    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(ROOT / "pyproject.toml", src)
    for tree in ("dfeif_codegen", "templates"):
        shutil.copytree(ROOT / tree, src / tree, ignore=shutil.ignore_patterns("__pycache__"))
    proc = subprocess.run([sys.executable, "-c", "import setuptools; setuptools.setup()", "-q", "build_py", "-d",
                           str(tmp_path / "out")], cwd=src, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    shipped = tmp_path / "out" / "dfeif_codegen"
    for name in ("py.typed", "api.py", "__main__.py"):
        assert (shipped / name).is_file(), f"{name} is not in the package (pyproject.toml)"
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert any(dep.startswith("mypy") for dep in data["project"]["optional-dependencies"]["test"])
    assert data["project"]["license"]["text"] == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n\nCopyright (c) 2026 dfeif-codegen authors")


def test_type_checkers_see_the_names_the_root_loads():
    """The lazy `_API` table and the imports under TYPE_CHECKING name the same objects."""
    tree = ast.parse((ROOT / "dfeif_codegen" / "__init__.py").read_text())
    block = next(n for n in tree.body if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING")
    typed = {(a.asname or a.name): (node.module, a.name) for node in block.body for a in node.names}
    assert typed == {name: tuple(where) for name, where in dc._API.items()}


def _codegen_errors(cls=None) -> set[type]:
    cls = cls or dc.CodegenError
    return {cls} | {sub for c in cls.__subclasses__() for sub in _codegen_errors(c)}


def test_every_error_a_user_can_meet_is_at_dc():
    """Every CodegenError subclass of the package (each module imported, so all are defined) and
    every C return code's class is exported, as itself. The CLI's own StaleError is `build
    --check`'s exit 1 (dc.check_build returns the list of stale files instead)."""
    import importlib

    for path in (ROOT / "dfeif_codegen").rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] not in ("__main__",):
            importlib.import_module(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    from dfeif_codegen.check import loader

    exported = {getattr(dc, name) for name in dc.__all__ if name != "__version__"}
    assert _codegen_errors() - {cli.StaleError} <= exported
    assert set(loader.ERRORS.values()) | {loader.CError} <= exported
    assert dc.SequenceError is loader.SequenceError and issubclass(dc.LagError, dc.CError)
    assert dc.ModelError.exit_code == 2 and dc.MismatchError.exit_code == 1


# CLI options that are not keywords of the command's function, and why
CLI_ONLY = {
    "build": {"check": "dc.check_build", "out": "the second positional argument"},
    "bench": {"out": "the CLI writes result.report() there"},
    "network": {"bench": "net/bench.py's measurements, written into BENCHMARKS.md"},
    "simulate": {"json": "json_path (json is a module name)"},
    "inspect": {"json": "the CLI prints inspect's dict as JSON"},
}
FUNCTIONS = {"build": dc.build, "verify": dc.verify, "simulate": dc.simulate, "scenario": dc.scenario,
             "inspect": dc.inspect, "network": dc.network, "bench": dc.bench, "reproduce": dc.reproduce}


def test_every_command_option_is_a_keyword_of_its_function():
    """Same names (the dest of each option) and the same defaults where the CLI states one."""
    subparsers = next(a for a in cli.parser()._actions if a.dest == "command").choices
    for command, fn in FUNCTIONS.items():
        params = inspect.signature(fn).parameters
        for action in subparsers[command]._actions:
            dest = action.dest
            if dest in ("help", "model") or dest in CLI_ONLY.get(command, {}):
                continue
            assert dest in params, f"codegen {command} --{dest.replace('_', '-')}: no keyword of dc.{command}"
            default = params[dest].default
            if action.default is not None and default is not inspect.Parameter.empty \
                    and not isinstance(action.default, bool):
                assert default == action.default, (command, dest, default, action.default)


def test_memory_budget_is_in_gigabytes_like_the_option():
    """dc.build(max_memory=...) in GB: an allocation of 0.5 GB fails under 0.2 and passes under 2,
    and the error names the budget as the user gave it."""
    from dfeif_codegen import budget

    def allocate(progress=None):
        return len(bytearray(500_000_000))

    if "fork" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("the budget needs fork (Linux, macOS)")
    assert budget.bounded(allocate, (), 60.0, 2.0, "probe") == 500_000_000
    with pytest.raises(dc.BudgetError, match=r"probe: .*0\.2 GB memory budget|raise --max-memory"):
        budget.bounded(allocate, (), 60.0, 0.2, "probe")
    # dc.build's default (None) is the budget module's, which is in GB like --max-memory's
    assert inspect.signature(dc.build).parameters["max_memory"].default is None
    assert budget.MAX_MEMORY == 2.0


def test_python_dash_m_runs_the_command(tmp_path):
    version = subprocess.run([sys.executable, "-m", "dfeif_codegen", "--version"], capture_output=True,
                             text=True, cwd=tmp_path, timeout=120)
    assert version.returncode == 0 and version.stdout.strip() == f"dfeif-codegen {dc.__version__}"
    bad = subprocess.run([sys.executable, "-m", "dfeif_codegen", "simulate", "--runs", "0", "--quiet"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert bad.returncode == 2 and bad.stderr.strip() == "codegen simulate: error: --runs: needs 1 to 100000, got 0"


def test_bench_result_json_keeps_every_measurement():
    """BenchResult.to_json: the per-build counts keyed "oosm/fusion", the sizes' dataclasses as
    objects, numbers unchanged."""
    import json

    from dfeif_codegen.check import target
    from dfeif_codegen.check.bench_report import BenchResult

    section = {"name": "m", "times": [1.5, 1.25], "counts": {("replay", "difference"): {"node_update": 385.0}},
               "sizes": {"m_node.o": target.Size(text=1200, data=0, bss=8)}}
    doc = json.loads(BenchResult("codegen bench", 3, {"gcc": "gcc 12"}, [section], {}).to_json())
    assert doc["sections"][0]["counts"] == {"replay/difference": {"node_update": 385.0}}
    assert doc["sections"][0]["sizes"] == {"m_node.o": {"text": 1200, "data": 0, "bss": 8}}
    assert doc["repeat"] == 3 and doc["sections"][0]["times"] == [1.5, 1.25]
