"""Shared fixtures: tool checks that skip on a user's machine and fail in CI, and cached builds."""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

IN_CI = os.environ.get("CI", "").lower() == "true"
_MISSING: dict[str, str] = {}


def _have(name: str) -> bool:
    if name.endswith(".specs"):  # a newlib specs file, found through the cross compiler
        gcc = shutil.which("arm-none-eabi-gcc")
        if gcc is None:
            return False
        out = subprocess.run([gcc, f"-print-file-name={name}"], capture_output=True, text=True)
        return Path(out.stdout.strip()).is_absolute()
    return shutil.which(name) is not None


def missing(reason: str) -> None:
    """Something a test needs is not installed: FAIL in CI (CI=true), SKIP elsewhere, saying what."""
    if IN_CI:
        pytest.fail(reason, pytrace=False)
    pytest.skip(reason)


def require_tool(name: str, package: str) -> str | None:
    """Path of tool `name`; if missing, FAIL in CI (CI=true) and SKIP elsewhere, naming the
    Debian package that provides it, so a user's `pytest` run stays green but says what it missed."""
    if _have(name):
        return shutil.which(name) or name
    if not IN_CI:
        _MISSING[name] = package
    missing(f"{name} not found: install the Debian package {package} (apt-get install {package})")
    return None


def require_module(name: str) -> None:
    """A Python package of the test extras (mypy, vermin): missing, as `missing` says."""
    try:
        importlib.import_module(name)
    except ImportError:
        missing(f"{name} not installed: pip install -e '.[test]'")


def pytest_terminal_summary(terminalreporter):
    """Print the skipped tools even under -q, where skip reasons are otherwise hidden."""
    for name, package in sorted(_MISSING.items()):
        terminalreporter.write_line(f"skipped tests need {name}: apt-get install {package}")


@pytest.fixture(scope="session")
def cross_tools():
    """The bare-metal Cortex-M4F route: compiler, newlib with semihosting, size, emulator."""
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    require_tool("rdimon.specs", "libnewlib-arm-none-eabi")
    require_tool("arm-none-eabi-size", "binutils-arm-none-eabi")
    require_tool("qemu-system-arm", "qemu-system-arm")


@pytest.fixture(scope="session")
def host_cc():
    """The host C compiler the harness uses (cc, as the harness picks it)."""
    from dfeif_codegen.check import harness

    name = os.path.basename(harness.host_compiler_name())
    require_tool(name, "gcc" if "gcc" in name or name == "cc" else name)
    return harness.host_compiler()


# --- builds and recordings, shared by the equivalence and target tests -----------------------

@dataclass(frozen=True)
class Case:
    """One recorded scenario: the paper scenario's settings with one delay row and reference,
    optionally with a lossy node -> master link and camera frame drops."""

    model: str = "dc_motor_link"
    oosm: str = "replay"
    fusion: str = "difference"
    reference: str = "sinusoid"
    row: int = 2
    max_lag: int = 32
    duration: float | None = None   # None: the scenario's 20 s
    uplink: tuple | None = None     # (p, d, p_drop) of the node -> master links
    sensor_drop: float | None = None
    predictor: str | None = None    # None: brunovsky with retrodict (the only one it takes), else held

    @property
    def prediction(self) -> str:
        from dfeif_codegen.reference import predictor

        return predictor.for_method(self.predictor, self.oosm)

    def build(self, precision: str) -> tuple:
        """What the generated C depends on (the key of a build)."""
        return (self.model, precision, self.oosm, self.fusion, self.max_lag, self.prediction)

    def __str__(self) -> str:
        net = "" if self.uplink is None else f"-uplink{self.uplink}-drop{self.sensor_drop}"
        lag = "" if self.max_lag == 32 else f"-maxlag{self.max_lag}"
        return f"{self.model}-{self.oosm}-{self.fusion}-{self.reference}-row{self.row}{lag}{net}-{self.prediction}"


def _record(case: Case):
    """The reference's closed-loop run (an experiment.Result, recording included)."""
    from dfeif_codegen.check import verify
    from dfeif_codegen.experiment.network import Link

    uplink = None if case.uplink is None else Link(*case.uplink)
    return verify.closed_loop(case.model, case.oosm, case.fusion, case.reference, case.row,
                              max_lag=case.max_lag, duration=case.duration, uplink=uplink,
                              sensor_drop=case.sensor_drop, predictor=case.prediction)


def _build(key: tuple, root: str) -> str:
    from dfeif_codegen.check import harness

    model, precision, oosm, fusion, max_lag, predictor = key
    out = Path(root) / "-".join(map(str, key))
    md = harness.build_model(model, out / "gen", precision, oosm, fusion, max_lag=max_lag, predictor=predictor)
    harness.Library(md, out / "lib")
    return str(md.path)


class Store:
    """Recordings and compiled builds, made once per session. The first request prepares every
    case and build the collected tests will ask for, in worker processes (one per core)."""

    def __init__(self, session, root: Path):
        self.session, self.root = session, root
        self.results: dict = {}
        self.models: dict = {}
        self.libraries: dict = {}
        self.prepared = False

    def _prepare(self) -> None:
        self.prepared = True
        cases, builds = set(), set()
        for item in self.session.items:
            params = getattr(getattr(item, "callspec", None), "params", {})
            for value in params.values():
                if isinstance(value, Case):
                    cases.add(value)
                if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], Case):
                    cases.add(value[0])
                    builds.add(value[0].build(value[1]))
        if not cases and not builds:
            return
        with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            recs = {c: pool.submit(_record, c) for c in cases}
            libs = {b: pool.submit(_build, b, str(self.root)) for b in builds}
            for c, fut in recs.items():
                try:
                    self.results[c] = fut.result()
                except Exception as exc:  # reported by the test that needs it
                    self.results[c] = exc
            for b, fut in libs.items():
                try:
                    self.models[b] = fut.result()
                except Exception as exc:
                    self.models[b] = exc

    def result(self, case: Case):
        if not self.prepared:
            self._prepare()
        if case not in self.results:
            self.results[case] = _record(case)
        res = self.results[case]
        if isinstance(res, Exception):
            raise res
        return res

    def recording(self, case: Case):
        return self.result(case).recording

    def library(self, case: Case, precision: str):
        from dfeif_codegen.check import harness

        if not self.prepared:
            self._prepare()
        key = case.build(precision)
        if key not in self.libraries:
            path = self.models.get(key) or _build(key, str(self.root))
            if isinstance(path, Exception):
                raise path
            md = harness.ModelDir.open(Path(path))
            self.libraries[key] = harness.Library(md, Path(path).parents[1] / "lib", reuse=True)
        return self.libraries[key]


@pytest.fixture(scope="session")
def store(request, tmp_path_factory, host_cc):
    return Store(request.session, tmp_path_factory.mktemp("builds"))
