"""The generated CMakeLists.txt as firmware and host projects use it, unmodified.

A minimal Cortex-M4F firmware project (tests/cmake/firmware, toolchain file cortex_m4f.cmake with
CMAKE_SYSTEM_NAME Generic) takes the module by add_subdirectory and, after a cross build and
`cmake --install`, by find_package; its main (tests/cmake/predict_check.c) is linked with the
harness startup code and linker script and run under QEMU, exit code = main's result. A host
project does the same under ctest. predict_check.c compares one node prediction with the closed
form of a chain of integrators, so a module that builds but computes wrongly fails here too.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import require_tool
from dfeif_codegen.check import target
from dfeif_codegen.codegen import build

HERE = Path(__file__).resolve().parent / "cmake"
MODEL = "dc_motor_link"


def run(cmd: list, cwd: Path | None = None, ok: bool = True) -> subprocess.CompletedProcess:
    result = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=600, cwd=cwd)
    if ok:
        assert result.returncode == 0, f"{' '.join(map(str, cmd))}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


def cmake_build(src: Path, out: Path, *defs: str) -> None:
    run(["cmake", "-S", src, "-B", out, *defs])
    run(["cmake", "--build", out])


def installed(module: Path, work: Path, *defs: str) -> Path:
    """Build the module as a top-level project, install it to a prefix; check what landed there."""
    prefix = work / "prefix"
    cmake_build(module, work / "lib", "-DCMAKE_BUILD_TYPE=Release", *defs)
    run(["cmake", "--install", work / "lib", "--prefix", prefix])
    for name in (f"include/{MODEL}.h", f"lib/lib{MODEL}.a", f"lib/cmake/{MODEL}/{MODEL}Config.cmake",
                 f"lib/cmake/{MODEL}/{MODEL}ConfigVersion.cmake", f"lib/cmake/{MODEL}/{MODEL}Targets.cmake"):
        assert (prefix / name).is_file(), name
    assert (prefix / f"include/{MODEL}_kernels.h").is_file(), "the kernels' prototypes are installed"
    assert not list((prefix / "include").glob("*_internal.h")), "the internal header is not installed"
    return prefix


@pytest.fixture(scope="module")
def modules(tmp_path_factory):
    """precision -> the generated module folder (default options otherwise; the Brunovsky predictor,
    whose one step predict_check.c knows in closed form)."""
    root = tmp_path_factory.mktemp("cmake-modules")
    return {prec: build.build(MODEL, root / prec, precision=prec, predictor="brunovsky").path
            for prec in ("double", "float")}


@pytest.mark.parametrize("how", ["add_subdirectory", "find_package"])
def test_firmware_project_for_cortex_m4f(modules, tmp_path, how):
    require_tool("cmake", "cmake")
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    require_tool("rdimon.specs", "libnewlib-arm-none-eabi")
    require_tool("qemu-system-arm", "qemu-system-arm")
    toolchain = f"-DCMAKE_TOOLCHAIN_FILE={HERE / 'cortex_m4f.cmake'}"
    module = modules["float"]  # float on the M4F: its libm calls (ceilf) must link under Generic
    if how == "add_subdirectory":
        where = f"-DMODULE_DIR={module}"
    else:
        where = f"-DCMAKE_FIND_ROOT_PATH={installed(module, tmp_path, toolchain)}"
    fw = tmp_path / "fw"
    cmake_build(HERE / "firmware", fw, toolchain, f"-DMODEL={MODEL}", where,
                f"-DHARNESS_DIR={target.harness_file('startup_cm4.c').parent}")
    elf = fw / "firmware.elf"
    header = elf.read_bytes()[:20]
    assert header[:4] == b"\x7fELF" and int.from_bytes(header[18:20], "little") == 40, "not an ARM ELF"
    result = run(["qemu-system-arm", *target.QEMU_ARGS, "-kernel", elf], cwd=tmp_path, ok=False)
    assert result.returncode == 0, f"firmware check failed on the emulated M4F: {result.stdout}{result.stderr}"


@pytest.mark.parametrize("how", ["add_subdirectory", "find_package"])
def test_host_project_runs_ctest(modules, tmp_path, how):
    require_tool("cmake", "cmake")
    require_tool("ctest", "cmake")
    module = modules["double"]
    where = f"-DMODULE_DIR={module}" if how == "add_subdirectory" else \
        f"-DCMAKE_PREFIX_PATH={installed(module, tmp_path)}"
    host = tmp_path / "host"
    cmake_build(HERE / "host", host, f"-DMODEL={MODEL}", where)
    result = run(["ctest", "--output-on-failure"], cwd=host)
    assert "100% tests passed, 0 tests failed out of 1" in result.stdout
    # the same check against a closed form with twice the period must fail: it is not vacuous
    wrong = tmp_path / "wrong"
    cmake_build(HERE / "host", wrong, f"-DMODEL={MODEL}", where,
                "-DCHECK_TS_SCALE=2")
    assert run(["ctest"], cwd=wrong, ok=False).returncode != 0


def test_example_builds_against_the_installed_package(tmp_path):
    """The default build's example program (held predictor: it simulates its plant with the
    kernels' mean map, declared in MODEL_kernels.h) compiles, links and passes against the
    installed package alone, the module's folder out of reach."""
    require_tool("cmake", "cmake")
    require_tool("ctest", "cmake")
    module = build.build(MODEL, tmp_path / "gen").path
    prefix = installed(module, tmp_path)
    example = shutil.copy(module / "example_main.c", tmp_path / "example_main.c")
    shutil.rmtree(tmp_path / "gen")
    host = tmp_path / "host"
    cmake_build(HERE / "host", host, f"-DMODEL={MODEL}", f"-DCMAKE_PREFIX_PATH={prefix}",
                f"-DEXAMPLE={example}", "-DPREDICT_CHECK=OFF")
    result = run(["ctest", "--output-on-failure"], cwd=host)
    assert "100% tests passed, 0 tests failed out of 1" in result.stdout and "module_example" in result.stdout


def test_module_runs_its_own_example_under_ctest(modules, tmp_path):
    """Top level on the host, the module builds its example and registers it with ctest."""
    require_tool("cmake", "cmake")
    shutil.copytree(modules["double"], tmp_path / "src")
    cmake_build(tmp_path / "src", tmp_path / "b")
    result = run(["ctest", "--output-on-failure"], cwd=tmp_path / "b")
    assert f"{MODEL}_example" in result.stdout and "100% tests passed" in result.stdout
