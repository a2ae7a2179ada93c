"""The Cortex-M4F bare-metal route on QEMU mps2-an386: the toolchain plumbing on a toy program,
then the generated filters on a recorded scenario (see test_equivalence for the host side)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from dfeif_codegen.check import target

pytestmark = pytest.mark.target

TOY = r"""
#include <stdio.h>
/* A scalar float Kalman filter: exercises the FPU, libm, printf and semihosting file output. */
int main(void)
{
    float x = 0.0f, p = 1.0f, out[2];
    for (int k = 0; k < 1000; k++) {
        float z = sinf(0.01f * (float)k);
        p = p + 1e-3f;
        float g = p / (p + 0.1f);
        x = x + g * (z - x);
        p = (1.0f - g) * p;
    }
    out[0] = x; out[1] = p;
    FILE *f = fopen("toy.bin", "wb");
    if (!f || fwrite(out, sizeof out, 1, f) != 1 || fclose(f) != 0) return 2;
    printf("done\n");
    return 7;
}
"""


def toy_reference() -> tuple[float, float]:
    x, p = 0.0, 1.0
    for k in range(1000):
        p += 1e-3
        g = p / (p + 0.1)
        x += g * (np.sin(0.01 * k) - x)
        p *= 1.0 - g
    return x, p


def test_toy_float_program_runs_on_qemu(tmp_path, cross_tools):
    src = tmp_path / "toy.c"
    src.write_text("#include <math.h>\n" + TOY)
    objs = target.compile_objects([src], tmp_path / "obj")
    elf = target.link(objs, tmp_path / "toy.elf")
    proc = target.run(elf, tmp_path, timeout=60)
    assert proc.stdout.strip() == "done"
    assert proc.returncode == 7, "main's return value becomes QEMU's exit code"
    x, p = struct.unpack("<2f", (tmp_path / "toy.bin").read_bytes())
    want_x, want_p = toy_reference()
    # single precision on the target against a double reference: a few dozen float32 roundings
    # (eps = 6e-8) on O(1) values stay below 1e-5, so 1e-4 holds on any IEEE float32 unit
    assert x == pytest.approx(want_x, rel=1e-4, abs=1e-5)
    assert p == pytest.approx(want_p, rel=1e-4)
    # the float build stays in single precision: no soft double calls, no double sin
    assert not {s for s in target.undefined_symbols(objs[0]) if s.startswith("__aeabi_d")}
    assert "sin" not in target.undefined_symbols(objs[0])


def test_fault_ends_emulation(tmp_path, cross_tools):
    src = tmp_path / "crash.c"
    src.write_text("int main(void) { void (*f)(void) = (void (*)(void))0x30000001u; f(); return 0; }\n")
    elf = target.link(target.compile_objects([src], tmp_path / "obj"), tmp_path / "crash.elf")
    proc = target.run(elf, tmp_path, timeout=30)
    assert proc.returncode == 1, "a hard fault exits QEMU through semihosting instead of hanging"


def test_sizes_and_stack_of_objects(tmp_path, cross_tools):
    src = tmp_path / "lib.c"
    src.write_text("float buf[16];\nfloat gain = 2.0f;\n"
                   "static float leaf(const float *a) { volatile float t[8]; t[0] = a[0]; return t[0]; }\n"
                   "float top(void) { float a[4] = {gain, 0, 0, 0}; buf[1] = leaf(a); return buf[1]; }\n")
    obj, = target.compile_objects([src], tmp_path / "obj", extra=["-fno-inline"])
    size = target.sizes([obj])["lib.o"]
    assert size.text > 0 and size.data == 4 and size.bss == 64
    use = target.stack_usage([obj.with_suffix(".ci")])
    leaf = use["top"].path[1]
    assert use["top"].path[0] == "top" and leaf.startswith("leaf")
    assert use[leaf].bytes >= 32 and use["top"].bytes > use[leaf].bytes and use["top"].bounded


def test_harness_files_ship_in_the_wheel(tmp_path):
    """The startup code, linker script and driver template are package data: build the package's
    Python tree the way a wheel is built (in a copy, leaving the work tree alone) and look there."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    root, src = Path(__file__).resolve().parents[1], tmp_path / "src"
    src.mkdir()
    shutil.copy(root / "pyproject.toml", src)
    for tree in ("dfeif_codegen", "templates"):
        shutil.copytree(root / tree, src / tree, ignore=shutil.ignore_patterns("__pycache__"))
    proc = subprocess.run([sys.executable, "-c", "import setuptools; setuptools.setup()", "-q",
                           "build_py", "-d", str(tmp_path / "out")], cwd=src, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    shipped = tmp_path / "out" / "dfeif_codegen" / "templates" / "harness"
    for name in ("startup_cm4.c", "mps2_an386.ld", "driver.c.j2"):
        assert (shipped / name).is_file(), f"{name} is not package data (pyproject.toml globs)"
    from dfeif_codegen.codegen.options import FUSION_RULES, OOSM_METHODS
    templates = [".clang-format", "node.c.j2", "master.c.j2", "kernels.h.j2"]
    templates += [f"node_{m}.c.j2" for m in OOSM_METHODS] + [f"master_{f}.c.j2" for f in FUSION_RULES]
    for name in templates:
        assert (shipped.parent / name).is_file(), f"{name} is not package data (pyproject.toml globs)"


# --- the generated filters on the emulated Cortex-M4F ----------------------------------------------

from conftest import Case  # noqa: E402
from conftest import require_tool  # noqa: E402
from dfeif_codegen.check import verify  # noqa: E402
from dfeif_codegen.check import driver_io

TARGET_RUNS = [(Case("dc_motor_link", "replay", "difference", "sinusoid", 1), "float"),
               (Case("two_link_arm", "retrodict", "paper", "seesaw", 1), "float"),      # Brunovsky
               (Case("two_link_arm", "replay", "difference", "seesaw", 2), "float"),    # held
               # scheduled: every step's P prior kept, so the replay's undo copies grow with the window
               # (node_update_delayed 4,184 B of stack at max_lag 32 in float): at 16, under the 4 KiB below
               (Case("two_link_arm", "replay", "difference", "seesaw", 5, max_lag=16, predictor="scheduled"), "float")]
DOUBLE_LIBM = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sqrt", "exp", "log", "pow", "ceil",
               "floor", "fabs", "fmod", "sinh", "cosh", "tanh"}


@pytest.mark.parametrize("run", TARGET_RUNS, ids=lambda r: str(r[0]))
def test_recorded_scenario_on_cortex_m4f(store, run, tmp_path, cross_tools):
    """The float build, cross-compiled at -O2, replays the whole 20 s recording on QEMU's
    mps2-an386; its outputs equal the float64 reference within the float tolerances."""
    case, precision = run
    model = store.library(case, precision).model
    rec = store.recording(case)
    result = target.run_scenario(model, rec, tmp_path, timeout=300)
    assert result.status["status"] == 0, driver_io.failure(result.status)
    errors = verify.compare_run(result.outputs, rec, precision)
    print(f"\n{case} on Cortex-M4F\n{verify.table(errors)}\n{target.report(result)}")
    assert all(s.data == 0 and s.bss == 0 for s in result.sizes.values()), "no static mutable data"
    for fn, use in result.stack.items():
        assert use.bytes < 4096, f"{fn} needs {use.bytes} bytes of stack"
        assert use.bounded or use.unknown, f"{fn}: unbounded stack (recursion or dynamic frame)"
    for obj in tmp_path.glob("lib/*.o"):
        imports = target.undefined_symbols(obj)
        assert not {s for s in imports if s.startswith("__aeabi_d")}, f"{obj.name} uses double arithmetic"
        assert not imports & DOUBLE_LIBM, f"{obj.name} calls double libm: {imports & DOUBLE_LIBM}"
    verify.check(errors)


def test_verify_command_on_cortex_m4f(store, monkeypatch, capsys, cross_tools):
    """`codegen verify --target cortex-m4f` prints the error table, sizes and stack, and its exit
    status says whether the table passed."""
    from dfeif_codegen import cli

    rec = store.recording(TARGET_RUNS[0][0])
    monkeypatch.setattr(verify, "record", lambda *a, **k: rec)
    rc = cli.main(["verify", "dc_motor_link", "--target", "cortex-m4f"])
    out = capsys.readouterr().out
    assert "Cortex-M4F library objects" in out and "worst-case stack" in out
    assert rc == (1 if "FAIL" in out else 0)


def test_a_run_larger_than_the_boards_ram_is_verified_on_its_beginning(store, monkeypatch, capsys, cross_tools):
    """The driver holds the run's inputs and one chunk of its outputs (it streams them to the
    host: tests/test_equivalence.py); a run whose inputs exceed the board's RAM (about 48,000
    steps of the motor in float) is checked on the longest beginning that fits (target.fitting,
    Recording.head), and verify says so. Here with the budget cut to the chunk and a third of
    the motor recording's inputs, the beginning's C outputs pass against the reference's own
    beginning (the filters are causal: the same numbers as the whole run's)."""
    from dfeif_codegen import cli

    case, precision = TARGET_RUNS[0]
    rec, model = store.recording(case), store.library(case, precision).model
    need, fixed = driver_io.driver_bytes(rec, model), driver_io.driver_bytes(rec.head(1), model)
    budget = fixed + (need - fixed) // 3
    monkeypatch.setattr(target, "HEAP_BUDGET", budget)
    head, steps = target.fitting(rec, model)
    whole = rec.ref.shape[0]
    assert driver_io.driver_bytes(head, model) <= budget and 0.25 * whole < steps < whole / 3 + 1
    monkeypatch.setattr(verify, "record", lambda *a, **k: rec)
    rc = cli.main(["verify", "dc_motor_link", "--target", "cortex-m4f"])
    out = capsys.readouterr().out
    assert f"the first {steps} of its {whole} steps" in out and rc == 0, out


def test_missing_cross_tool_is_a_setup_error(monkeypatch):
    from dfeif_codegen.errors import SetupError

    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(SetupError, match="apt-get install qemu-system-arm"):
        target.require("qemu-system-arm")


@pytest.mark.parametrize("run", [TARGET_RUNS[0]], ids=["dc_motor_link-float"])
def test_bench_measures_deterministically(store, run, tmp_path, cross_tools):
    """`codegen bench`'s figures for one build: instruction counts repeat exactly, every section
    is measured, struct sizes come from the target compiler."""
    from dfeif_codegen.check import bench_stages as bench, harness
    from dfeif_codegen.check.bench_measure import measure

    require_tool("valgrind", "valgrind")
    model = store.library(*run).model
    first, again = measure(bench.callgrind(model, tmp_path / "a")), measure(bench.callgrind(model, tmp_path / "b"))
    assert first == again
    assert set(first) == {"node_update", "node_predict", "master_fuse", "master_fuse_distinct", "control",
                          "node_update_delayed_lag1", "node_update_delayed_lag8", "node_update_delayed_lag25",
                          "node_update_delayed_lag32"}
    lags = [first[f"node_update_delayed_lag{lag}"] for lag in (1, 8, 25, 32)]
    assert lags == sorted(lags) and len(set(lags)) == 4   # a longer window replays more steps
    # the CI search: identical nodes converge in its first step, distinct ones take more, and the
    # worst-case build (-D<MODEL>_CI_TOL=-1) runs every one of ci_iterations(2) steps
    ci = harness.build_model("dc_motor_link", tmp_path / "ci", "double", "replay", "ci", 2)
    normal = measure(bench.callgrind(ci, tmp_path / "ci-a"))
    every = measure(bench.callgrind(ci, tmp_path / "ci-b", bench.ci_every_step(ci)))
    assert normal["master_fuse"] < normal["master_fuse_distinct"] < every["master_fuse_distinct"]
    sizes = target.struct_sizes(model, tmp_path / "sizeof")
    assert sizes["packet"] == 4 + 4 * (1 + 2 * 3 + 2 * 9)  # step + centre, x, P, x_pred, P_pred in float
