"""The generated C: strict compiles (gcc, clang, both precisions), a clean Cortex-M4F float build,
the static rules, C test programs (instances, error codes leave the state bit-identical) and a
quick numerical check against a few lines of numpy through ctypes.

A missing compiler skips its tests with the reason, unless CI=true, where it fails.
"""

from __future__ import annotations

import ctypes
import functools
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from dfeif_codegen import angles
from dfeif_codegen.codegen import build, output, render
from dfeif_codegen.codegen.options import Options
from dfeif_codegen.symbolic import discretize, flatness, model

WARN = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow", "-Wdouble-promotion",
        "-Wfloat-conversion", "-Wcast-qual", "-Wstrict-prototypes", "-Wmissing-prototypes", "-Wvla", "-Werror"]
ARM = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", "-Os"]
DOUBLE_MATH = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log",
               "sqrt", "ceil", "floor", "fabs", "fmin", "fmax", "pow", "fmod", "hypot", "round", "trunc"}

# (model, options): what the compile matrix covers
VARIANTS = {
    "dc-double": ("dc_motor_link", {}),
    "dc-float": ("dc_motor_link", {"precision": "float"}),
    "dc-retro-ci": ("dc_motor_link", {"oosm": "retrodict", "fusion": "ci"}),
    "dc-ci3": ("dc_motor_link", {"fusion": "ci", "nodes": 3}),
    "dc-ci16": ("dc_motor_link", {"fusion": "ci", "nodes": 16}),
    # 16 nodes: the CI step through the Hessian's factor (kernels/ci.py ci_kernels), in single precision
    "dc-float-ci16": ("dc_motor_link", {"precision": "float", "fusion": "ci", "nodes": 16}),
    "dc-float-retro-ci3": ("dc_motor_link", {"precision": "float", "oosm": "retrodict", "fusion": "ci", "nodes": 3}),
    "dc-float-paper": ("dc_motor_link", {"precision": "float", "fusion": "paper", "max_lag": 5}),
    # the smallest late-measurement windows: the example's late frame must fit them
    "dc-lag1": ("dc_motor_link", {"max_lag": 1}),
    "dc-float-retro-lag2": ("dc_motor_link", {"precision": "float", "oosm": "retrodict", "max_lag": 2}),
    "dc-float-retro-ci": ("dc_motor_link", {"precision": "float", "oosm": "retrodict", "fusion": "ci"}),
    # the chapter's Brunovsky predictor with replay (the default is the held-input predictor)
    "dc-brunovsky": ("dc_motor_link", {"predictor": "brunovsky"}),
    "arm-float-held": ("two_link_arm", {"precision": "float"}),
    # the scheduled transition: Φ(σ) from the broadcast flat outputs, every step's P prior kept
    "arm-double-scheduled": ("two_link_arm", {"predictor": "scheduled"}),
    "dc-float-scheduled-ci": ("dc_motor_link", {"precision": "float", "predictor": "scheduled", "fusion": "ci"}),
    # disturbance states (codegen build --disturbance): the state extended, q by their densities
    "dc-float-disturbance": ("dc_motor_link", {"precision": "float", "disturbance": "random_walk"}),
    "arm-double-gauss-markov": ("two_link_arm", {"disturbance": "gauss_markov", "tau": 0.5}),
    "arm-float-integrated": ("two_link_arm", {"precision": "float", "disturbance": "integrated_random_walk"}),
    "arm-float-scheduled-walk": ("two_link_arm", {"precision": "float", "predictor": "scheduled",
                                                  "disturbance": "random_walk"}),
    "arm-double": ("two_link_arm", {}),
    # the innovation gate (--gate): on time, in the replay and in the retrodiction
    "dc-gate": ("dc_motor_link", {"gate": 0.5}),
    "arm-float-retro-gate": ("two_link_arm", {"precision": "float", "oosm": "retrodict", "gate": 4.0}),
    "arm-float-retro-ci": ("two_link_arm", {"precision": "float", "oosm": "retrodict", "fusion": "ci"}),
    # no parameters: the parameter arrays still have an element (ISO C has no empty arrays)
    "free-double": (str(Path(__file__).parent / "data" / "free_cart.toml"), {}),
    "free-float": (str(Path(__file__).parent / "data" / "free_cart.toml"), {"precision": "float"}),
    # a dynamic extension: the controller's integrators (extension_step)
    "pvtol-float": ("pvtol", {"precision": "float"}),
    "unicycle-double": ("unicycle", {}),
    # a chain of 10 integrators (bench_peers.chain_model(10)): the held node_predict as loops
    "chain10-float": (str(Path(__file__).parent / "data" / "chain10.toml"), {"precision": "float"}),
}
FLOAT_VARIANTS = [k for k, (_, o) in VARIANTS.items() if o.get("precision") == "float"]


def tool(name: str) -> str:
    """Path of a tool, or skip (fail under CI=true) with the reason."""
    path = shutil.which(name)
    if path is None:
        message = f"{name} not found on PATH"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{message} (required when CI=true)")
        print(f"skipping: {message}")
        pytest.skip(message)
    return path


@functools.lru_cache(maxsize=None)
def _flat(name: str):
    return flatness.derive(model.load(name))


def render_files(name: str, **opts) -> dict[str, str]:
    flat = _flat(name)
    opts.setdefault("ts", flat.model.ts)
    return render.render(build.context(flat, Options(**opts)))


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    """variant -> folder with the generated module (rendered once per session)."""
    root = tmp_path_factory.mktemp("gen")
    cache: dict[str, Path] = {}

    def get(variant: str) -> Path:
        if variant not in cache:
            name, opts = VARIANTS[variant]
            cache[variant] = output.write_atomic(root / variant, _flat(name).model.name, render_files(name, **opts))
        return cache[variant]
    return get


def sources(folder: Path, example: bool = False) -> list[Path]:
    return sorted(p for p in folder.glob("*.c") if example or p.name != "example_main.c")


def run(cmd: list, **kw) -> subprocess.CompletedProcess:
    out = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=300, **kw)
    assert out.returncode == 0, f"{' '.join(map(str, cmd))}\n{out.stdout}\n{out.stderr}"
    return out


# --- strict compiles ----------------------------------------------------------------------------

@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_strict_compile(built, tmp_path, cc, variant):
    compiler = tool(cc)
    folder = built(variant)
    for src in sources(folder, example=True):
        run([compiler, *WARN, "-O2", "-I", folder, "-c", src, "-o", tmp_path / (src.stem + ".o")])


@pytest.mark.parametrize("variant", ["dc-double", "dc-float", "dc-retro-ci", "arm-float-retro-ci",
                                     "dc-float-disturbance", "dc-gate"])
def test_example_runs(built, tmp_path, variant):
    cc = tool("gcc")
    folder = built(variant)
    exe = tmp_path / "example"
    run([cc, *WARN, "-O2", "-I", folder, *sources(folder, example=True), "-lm", "-o", exe])
    out = run([exe]).stdout
    assert "RMS error" in out and "late applied" in out


@pytest.mark.parametrize("variant", ["dc-lag1", "dc-float-retro-lag2"])
def test_example_runs_with_a_short_window(built, tmp_path, variant):
    """--max-lag 1 or 2: the example's late frames (every 5th of node 1's, 60 in 300 steps)
    arrive within the window and are all applied (a lag of 3 was refused: "error at step 3")."""
    cc = tool("gcc")
    folder = built(variant)
    exe = tmp_path / "example"
    run([cc, *WARN, "-O2", "-I", folder, *sources(folder, example=True), "-lm", "-o", exe])
    out = run([exe]).stdout
    assert "node 1: updates 240, drops 60, late applied 60, late rejected 0" in out, out


def arm_objects(folder, out_dir, flags) -> list:
    """Every library source of `folder` compiled for the Cortex-M4F with `flags`."""
    cc = tool("arm-none-eabi-gcc")
    objects = []
    for src in sources(folder):
        obj = out_dir / (src.stem + ".o")
        run([cc, *ARM, *flags, "-I", folder, "-c", src, "-o", obj])
        objects.append(obj)
    return objects


@pytest.mark.parametrize("variant", FLOAT_VARIANTS)
def test_arm_float_objects_have_no_double(built, tmp_path, variant):
    nm = tool("arm-none-eabi-nm")
    objects = arm_objects(built(variant), tmp_path, WARN)
    symbols = run([nm, "-u", *objects]).stdout.split()
    assert not [s for s in symbols if s.startswith("__aeabi_d") or s in DOUBLE_MATH], symbols


@pytest.mark.parametrize("variant", ["dc-float", "dc-float-retro-ci"])
def test_arm_sizes_within_budget(built, tmp_path, variant):
    """Node + master + control objects of dc_motor_link at -Os: .text <= 16 KiB, no .data/.bss;
    the wire codec (optional for a firmware that does not use it) on its own <= 3 KiB."""
    size = tool("arm-none-eabi-size")
    objects = arm_objects(built(variant), tmp_path, ["-std=c99"])
    wire = [o for o in objects if o.stem.endswith("_wire")]
    for group, limit in ((sorted(set(objects) - set(wire)), 16 * 1024), (wire, 3 * 1024)):
        table = run([size, "-t", *group]).stdout.splitlines()
        print("\n".join(table))
        text, data, bss = (int(v) for v in table[-1].split()[:3])
        assert text <= limit and data == 0 and bss == 0


def test_float_sources_have_no_double_literals_or_calls(built):
    folder = built("dc-float-retro-ci3")
    for src in sources(folder):
        code = re.sub(r"/\*.*?\*/", "", src.read_text(), flags=re.S)
        calls = re.findall(r"(?<![\w.])(" + "|".join(sorted(DOUBLE_MATH)) + r")\(", code)
        literals = re.findall(r"(?<![\w.])\d+\.\d*(?:[eE][+-]?\d+)?(?![\w.])", code)
        assert not calls and not literals, (src.name, calls[:5], literals[:5])


# --- static rules ---------------------------------------------------------------------------------

ALLOWED_INCLUDES = {"<math.h>", "<stdint.h>", "<stddef.h>", "<string.h>"}


@pytest.mark.parametrize("variant", ["dc-double", "dc-float-retro-ci3", "arm-double"])
def test_static_rules(built, variant):
    folder = built(variant)
    files = sources(folder) + sorted(p for p in folder.glob("*.h"))
    for path in files:
        code = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
        for bad in (r"\bmalloc\b", r"\bcalloc\b", r"\brealloc\b", r"\bfree\s*\(", r"\bprintf\b", r"\bFILE\b",
                    r"\balloca\b", r"\bgoto\b"):
            assert not re.search(bad, code), (path.name, bad)
        for inc in re.findall(r'#include\s+(\S+)', code):
            assert inc in ALLOWED_INCLUDES or inc.startswith('"'), (path.name, inc)
        for line in code.splitlines():
            stripped = line.strip()
            # static data must be const; static functions are fine (a '(' before any '=')
            if stripped.startswith("static ") and "const" not in stripped.split("=")[0]:
                assert "(" in stripped.split("=")[0], (path.name, line)
        # VLA pattern: an array declared with a lower-case (runtime) size
        assert not re.search(r"\b(?:real|double|float|int)\s+\w+\[[a-z_][a-z_0-9]*\]", code), path.name


# --- C test programs ------------------------------------------------------------------------------

C_TEST = r"""
#include <stdio.h>
#include <string.h>
#include HEADER
#define XC(a, b) a##_##b
#define C(a, b) XC(a, b)
#define F(n) C(PFX, n)
#define K(n) C(UP, n)
#define NX K(NX)
#define NY K(NY)
typedef F(real) real;
static int fails = 0;
#define CHECK(c) do { if (!(c)) { printf("FAIL line %d: %s\n", __LINE__, #c); fails++; } } while (0)
#define SAME(a, b) (memcmp(&(a), &(b), sizeof(a)) == 0)

static void init(F(node) *nd, real p0)
{
    real x0[NX], P0[NX * NX], R[NY * NY], q[NY];
    int i;
    memset(x0, 0, sizeof(x0));
    memset(P0, 0, sizeof(P0));
    memset(R, 0, sizeof(R));
    for (i = 0; i < NX; i++) P0[i * NX + i] = p0;
    for (i = 0; i < NY; i++) { R[i * NY + i] = (real)1e-4; q[i] = 1; }
    CHECK(F(node_init)(nd, x0, P0, R, q) == K(OK));
}

static void step(F(node) *nd, int k, real scale)
{
    real z[NY], v[NY];
    int j;
    for (j = 0; j < NY; j++) { z[j] = scale * (real)(k % 7) / 10; v[j] = (real)(k % 3) - 1; }
    CHECK(F(node_update)(nd, z, k % 4 != 1) == K(OK));
    CHECK(F(node_predict)(nd, v) == K(OK));
}

int main(void)
{
    static F(node) a, b, c, snap, tmp;
    static F(master) m, msnap;
    static F(packet) pk[K(NNODES)];
    uint8_t present[K(NNODES)];
    real z[NY], v[NY], x[NX], P[NX * NX], Y[NX * NX], flags[K(NFLAGS)], gains[NX], params[K(NP)];
    real u[NY], x0[NX], P0[NX * NX], R[NY * NY], q[NY];
    volatile real zero = 0;
    real nan = zero / zero;
    int i, k;
    static F(master) mtwin;
    static F(packet) lagged[4], lagged_c[4], two[K(NNODES)], flat_twin[K(NNODES)];

    /* two instances interleaved equal one run alone */
    init(&a, 1); init(&b, 2); init(&c, 1);
    for (k = 0; k < 20; k++) { step(&a, k, 1); step(&b, k, -3); }
    for (k = 0; k < 20; k++) step(&c, k, 1);
    CHECK(SAME(a, c));
    CHECK(F(node_size)() == sizeof(F(node)) && F(master_size)() == sizeof(F(master)));
    CHECK(F(packet_size)() == sizeof(F(packet)));

    for (i = 0; i < NY; i++) { z[i] = (real)0.1; v[i] = 0; }
    /* step 20, not updated yet */
    snap = a;
    CHECK(F(node_predict)(&a, v) == K(ERR_SEQUENCE) && SAME(a, snap));
    CHECK(F(node_update_delayed)(&a, z, 1) == K(ERR_SEQUENCE) && SAME(a, snap));
    CHECK(F(node_update)(NULL, z, 1) == K(ERR_ARG));
    CHECK(F(node_update)(&a, z, 2) == K(ERR_ARG) && SAME(a, snap));
    CHECK(F(node_update)(&a, z, -1) == K(ERR_ARG) && SAME(a, snap));
    CHECK(F(node_update)(&a, NULL, 1) == K(ERR_ARG) && SAME(a, snap));
    z[0] = nan;
    CHECK(F(node_update)(&a, z, 1) == K(ERR_NONFINITE) && SAME(a, snap));
    z[0] = (real)0.1;
    CHECK(F(node_update)(&a, z, 1) == K(OK));
    snap = a;
    CHECK(F(node_update)(&a, z, 1) == K(ERR_SEQUENCE) && SAME(a, snap));
    v[0] = nan;
    CHECK(F(node_predict)(&a, v) == K(ERR_NONFINITE) && SAME(a, snap));
    v[0] = 0;
    CHECK(F(node_predict)(NULL, v) == K(ERR_ARG) && F(node_predict)(&a, NULL) == K(ERR_ARG) && SAME(a, snap));

    /* late measurements: rejected ones only count */
    tmp = snap;
    tmp.health.late_rejected++;
    CHECK(F(node_update_delayed)(&a, z, 0) == K(ERR_LAG) && SAME(a, tmp));
    a = snap;
    CHECK(F(node_update_delayed)(&a, z, K(NMAX) + 1) == K(ERR_LAG) && SAME(a, tmp));
    a = snap;
    CHECK(F(node_update_delayed)(&a, z, -5) == K(ERR_LAG) && SAME(a, tmp));
    a = snap;
    CHECK(F(node_update_delayed)(&a, z, 2) == K(ERR_DUPLICATE) && SAME(a, tmp));  /* step 18: on time */
    a = snap;
    z[0] = nan;
    CHECK(F(node_update_delayed)(&a, z, 3) == K(ERR_NONFINITE) && SAME(a, snap));
    z[0] = (real)0.1;
    CHECK(F(node_update_delayed)(NULL, z, 3) == K(ERR_ARG) && F(node_update_delayed)(&a, NULL, 3) == K(ERR_ARG));
    CHECK(F(node_update_delayed)(&a, z, 3) == K(OK));  /* step 17 was dropped (17 % 4 == 1) */
    CHECK(a.health.late_applied == 1);
    snap = a;
    tmp = snap;
    tmp.health.late_rejected++;
    CHECK(F(node_update_delayed)(&a, z, 3) == K(ERR_DUPLICATE) && SAME(a, tmp));
    init(&c, 1);
    CHECK(F(node_update)(&c, z, 1) == K(OK));
    snap = c;
    tmp = c;
    tmp.health.late_rejected++;
    CHECK(F(node_update_delayed)(&c, z, 1) == K(ERR_LAG) && SAME(c, tmp));  /* lag > k */
    /* started mid-run (node_mid_run): no late frame of a step before the first measurement */
    for (i = 0; i < 2; i++) {
        init(&c, 1);
        CHECK(F(node_mid_run)(NULL) == K(ERR_ARG));
        CHECK(i == 0 || F(node_mid_run)(&c) == K(OK));
        CHECK(F(node_update)(&c, NULL, 0) == K(OK) && F(node_predict)(&c, v) == K(OK));  /* step 0 lost */
        CHECK(F(node_update)(&c, z, 1) == K(OK));                                       /* step 1 */
        CHECK(F(node_mid_run)(&c) == K(ERR_SEQUENCE));
        snap = c;
        tmp = c;
        tmp.health.late_rejected++;
        if (i == 1) {   /* step 0 holds the prior alone */
            CHECK(F(node_update_delayed)(&c, z, 1) == K(ERR_LAG) && SAME(c, tmp));
        } else {        /* a node started at step 0 takes it */
            CHECK(F(node_update_delayed)(&c, z, 1) == K(OK) && c.health.late_applied == 1);
        }
        CHECK(F(node_predict)(&c, v) == K(OK) && F(node_update)(&c, NULL, 0) == K(OK));  /* step 2 lost */
        CHECK(F(node_predict)(&c, v) == K(OK) && F(node_update)(&c, z, 1) == K(OK));     /* step 3 */
        CHECK(F(node_update_delayed)(&c, z, 1) == K(OK) && c.health.late_applied == 2u - (uint32_t)i);
    }

    /* step numbers wrap at 2^32 (no ring size divides it): a node and a master relabelled to
     * 2^32 - 100 (a multiple of the checkpoints' period: init starts at 0, and 2^32 is one) run
     * across the wrap beside unlabelled twins, with drops, late frames and stale packets, and
     * stay equal to them bit for bit; only their step numbers differ, by the relabelling */
    init(&b, 1); init(&c, 1);
    memset(x0, 0, sizeof(x0)); memset(P0, 0, sizeof(P0));
    for (i = 0; i < NX; i++) P0[i * NX + i] = 1;
    for (i = 0; i < NY; i++) { q[i] = 1; v[i] = (real)0.01; }
    CHECK(F(master_init)(&m, x0, P0, q) == K(OK));
    mtwin = m;
    c.k = 0u - 100u;
    m.k = 0u - 100u;
    for (i = 0; i < K(NNODES); i++) present[i] = (uint8_t)(i == 0);
    for (k = 0; k < 200; k++) {
        for (i = 0; i < NY; i++) z[i] = (real)(k % 7) / 100;
        CHECK(F(node_update)(&b, z, k % 4 != 1) == K(OK) && F(node_update)(&c, z, k % 4 != 1) == K(OK));
        if (k >= 3) {   /* step k - 3's frame arrives late: applied when that step was lost */
            CHECK(F(node_update_delayed)(&b, z, 3) == F(node_update_delayed)(&c, z, 3));
        }
        CHECK(F(node_packet)(&b, &lagged[k % 4]) == K(OK) && F(node_packet)(&c, &lagged_c[k % 4]) == K(OK));
        CHECK(lagged_c[k % 4].step - lagged[k % 4].step == 0u - 100u);
        /* at odd steps the packet of 3 steps before, at even ones none: each packet stale and
         * newer than the last one fused (the difference rule then takes its gain over the last
         * one brought forward: the lost packets' channel) */
        i = (k + 1) % 4;
        present[0] = (uint8_t)((k % 2 == 1) && (k >= 3));
        two[0] = lagged[i];
        flat_twin[0] = lagged_c[i];
        CHECK(F(master_fuse)(&mtwin, two, present) == K(OK) && F(master_fuse)(&m, flat_twin, present) == K(OK));
        CHECK(SAME(m.x, mtwin.x) && SAME(m.P, mtwin.P));
        CHECK(F(node_predict)(&b, v) == K(OK) && F(node_predict)(&c, v) == K(OK));
        CHECK(F(master_predict)(&mtwin, v) == K(OK) && F(master_predict)(&m, v) == K(OK));
    }
    CHECK(c.k == b.k - 100u && c.k < 1000u && b.health.late_applied > 20u);
    CHECK(SAME(c.post, b.post) && SAME(c.pred, b.pred) && SAME(c.ring_x, b.ring_x) && SAME(c.ring_P, b.ring_P));
    CHECK(SAME(c.health, b.health) && SAME(m.health, mtwin.health) && m.health.packets_stale > 20u);
    CHECK(m.health.packets_ignored == 0u);

    /* init validates before touching the node */
    memset(x0, 0, sizeof(x0)); memset(P0, 0, sizeof(P0)); memset(R, 0, sizeof(R));
    for (i = 0; i < NX; i++) P0[i * NX + i] = 1;
    for (i = 0; i < NY; i++) { R[i * NY + i] = 1; q[i] = 1; }
    snap = a;
    R[0] = -1;
    CHECK(F(node_init)(&a, x0, P0, R, q) == K(ERR_SINGULAR) && SAME(a, snap));
    R[0] = 1; q[0] = -1;
    CHECK(F(node_init)(&a, x0, P0, R, q) == K(ERR_ARG) && SAME(a, snap));
    q[0] = 1; x0[0] = nan;
    CHECK(F(node_init)(&a, x0, P0, R, q) == K(ERR_NONFINITE) && SAME(a, snap));
    x0[0] = 0;
    CHECK(F(node_init)(NULL, x0, P0, R, q) == K(ERR_ARG));

    /* information of a non-positive-definite covariance */
    tmp = a;
    /* P = -I in the node's packed upper triangle (column j holds entries 0..j, the diagonal last),
     * stored after x in the node's estimate */
    for (i = 0; i < K(NPP); i++) tmp.post[NX + i] = 0;
    for (i = 0; i < NX; i++) tmp.post[NX + (i * (i + 1)) / 2 + i] = -1;
    snap = tmp;
    for (i = 0; i < NX * NX; i++) Y[i] = 7;
    CHECK(F(node_information)(&tmp, Y, x) == K(ERR_SINGULAR) && SAME(tmp, snap) && Y[0] == 7);
    CHECK(F(node_information)(&a, Y, x) == K(OK));

    /* master */
    CHECK(F(master_init)(&m, x0, P0, q) == K(OK));
    for (i = 0; i < K(NNODES); i++) { CHECK(F(node_packet)(&a, &pk[i]) == K(OK)); pk[i].step = 0; present[i] = 1; }
    msnap = m;
    CHECK(F(master_fuse)(NULL, pk, present) == K(ERR_ARG) && F(master_fuse)(&m, NULL, present) == K(ERR_ARG));
    pk[0].x[0] = nan;
    CHECK(F(master_fuse)(&m, pk, present) == K(ERR_NONFINITE) && SAME(m, msnap));
    pk[0].x[0] = 0;
    pk[0].P[0] = -1;
    CHECK(F(master_fuse)(&m, pk, present) == K(ERR_SINGULAR) && SAME(m, msnap));
    pk[0].P[0] = 1;
    pk[0].step = 5;  /* from the future: ignored */
    CHECK(F(master_fuse)(&m, pk, present) == K(OK) && m.health.packets_ignored == 1);
    v[0] = nan;
    msnap = m;
    CHECK(F(master_predict)(&m, v) == K(ERR_NONFINITE) && SAME(m, msnap));

    CHECK(F(master_estimate)(&m, x, P) == K(OK) && F(master_estimate)(NULL, x, P) == K(ERR_ARG));

    /* control */
    for (i = 0; i < K(NFLAGS); i++) flags[i] = 0;
    for (i = 0; i < NX; i++) gains[i] = 1;
    memcpy(params, F(params_default), sizeof(params));
    CHECK(F(control)(x, flags, gains, params, u, NULL, NULL) == K(OK));
    u[0] = 42;
    CHECK(F(control)(NULL, flags, gains, params, u, v, NULL) == K(ERR_ARG));
    flags[0] = nan;
    CHECK(F(control)(x, flags, gains, params, u, v, NULL) == K(ERR_NONFINITE) && u[0] == 42);
    flags[0] = 0;
    memset(params, 0, sizeof(params));
    CHECK(F(control)(x, flags, gains, params, u, v, NULL) == K(ERR_SINGULAR) && u[0] == 42);
    CHECK(F(gains)(NULL, gains) == K(ERR_ARG));

    printf(fails ? "FAILED\n" : "ok\n");
    return fails ? 1 : 0;
}
"""


@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("variant", ["dc-double", "dc-float", "dc-retro-ci", "arm-float-retro-ci"])
def test_c_api_errors_and_instances(built, tmp_path, cc, variant):
    compiler = tool(cc)
    folder = built(variant)
    name = VARIANTS[variant][0]
    src = tmp_path / "api_test.c"
    src.write_text(C_TEST)
    exe = tmp_path / "api_test"
    run([compiler, *WARN, "-Wno-missing-prototypes", "-O1", f'-DHEADER="{name}.h"', f"-DPFX={name}",
         f"-DUP={name.upper()}", "-I", folder, src, *sources(folder), "-lm", "-o", exe])
    assert run([exe]).stdout.strip().endswith("ok")


# --- numbers through ctypes -----------------------------------------------------------------------

def shared_library(folder: Path, tmp: Path) -> ctypes.CDLL:
    cc = tool("gcc")
    so = tmp / f"lib{folder.name}.so"
    run([cc, "-std=c99", "-O2", "-fPIC", "-shared", "-I", folder, *sources(folder), "-lm", "-o", so])
    return ctypes.CDLL(str(so))


class Lib:
    """Thin ctypes access: every array is a float64 numpy array passed by pointer."""

    def __init__(self, cdll: ctypes.CDLL, name: str):
        self.c, self.p = cdll, name
        for f in ("node_size", "master_size", "packet_size"):
            getattr(cdll, f"{name}_{f}").restype = ctypes.c_size_t

    def __call__(self, fn: str, *args) -> int:
        conv = [a.ctypes.data_as(ctypes.c_void_p) if isinstance(a, np.ndarray) else a for a in args]
        return getattr(self.c, f"{self.p}_{fn}")(*conv)

    def new(self, kind: str):
        return ctypes.create_string_buffer(getattr(self.c, f"{self.p}_{kind}_size")())


def wrap(e):
    return e - 2 * np.pi * np.ceil((e - np.pi) / (2 * np.pi))


def test_node_matches_numpy(built, tmp_path):
    folder = built("dc-double")
    lib = Lib(shared_library(folder, tmp_path), "dc_motor_link")
    from dfeif_codegen.reference import predictor as predictors

    flat = _flat("dc_motor_link")
    C = flat.discrete(flat.model.ts)[2]
    q = np.array([3.0])
    pred = predictors.make("held", flat, flat.model.ts, q)     # the default build's predictor
    A, Q = pred.Phi, pred.Q
    R = np.array([[2e-4]])
    x, P = np.array([0.3, -0.1, 0.2]), np.diag([1e-2, 1e-1, 1.0])
    node = lib.new("node")
    assert lib("node_init", node, x.copy(), P.copy(), R.copy(), q.copy()) == 0
    rng = np.random.default_rng(7)
    for k in range(25):
        z = np.array([3.1 if k == 5 else rng.normal(0.3, 0.05)])  # k = 5 exercises the angle wrap
        gamma = int(k % 6 != 2)
        e = wrap(z - C @ x)
        S = C @ P @ C.T + R
        K = gamma * P @ C.T @ np.linalg.inv(S)
        IKC = np.eye(3) - K @ C
        x, P = x + K @ e, IKC @ P @ IKC.T + K @ R @ K.T
        assert lib("node_update", node, z, gamma) == 0
        got_x, got_P = np.zeros(3), np.zeros(9)
        lib("node_estimate", node, got_x, got_P)
        # numpy's Joseph form against the C's P - K C P (heads' row R K'): equal in exact
        # arithmetic, a few dozen flops per entry of a well-conditioned 3x3 P, each rounding once
        # (eps = 1.1e-16), so 1e-12 relative is ~100x the worst accumulation on any IEEE
        # machine; atol covers entries that cancel to ~0
        np.testing.assert_allclose(got_x, x, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(got_P.reshape(3, 3), P, rtol=1e-12, atol=1e-16)
        u = np.array([np.sin(0.3 * k)])
        x, P = pred.mean(x, u), A @ P @ A.T + Q
        assert lib("node_predict", node, u) == 0
    Y, y = np.zeros(9), np.zeros(3)
    assert lib("node_information", node, Y, y) == 0
    # two backward-stable inversions of a 3x3 differ by at most ~2 n cond(P) eps relative,
    # whatever LAPACK kernel numpy picks; with cond(P) < 1e5 (checked) that is 7e-11 < 1e-9
    assert np.linalg.cond(P) < 1e5
    np.testing.assert_allclose(Y.reshape(3, 3), np.linalg.inv(P), rtol=1e-9)
    np.testing.assert_allclose(y, np.linalg.solve(P, x), rtol=1e-9)


def _run_late(lib: Lib, late_lag: int, drops=(30, 33, 35)) -> tuple[np.ndarray, np.ndarray]:
    node = lib.new("node")
    assert lib("node_init", node, np.zeros(3), np.diag([1e-2, 1e-1, 1.0]), np.array([1e-4]), np.array([10.0])) == 0
    zs = {k: np.array([0.1 * np.sin(0.05 * k) + 0.01 * np.cos(1.7 * k)]) for k in range(40)}
    for k in range(40):
        assert lib("node_update", node, zs[k], int(k not in drops)) == 0
        if k == 39 and late_lag:
            assert lib("node_update_delayed", node, zs[39 - late_lag], ctypes.c_int32(late_lag)) == 0
        if k < 39:
            assert lib("node_predict", node, np.array([np.cos(0.1 * k)])) == 0
    x, P = np.zeros(3), np.zeros(9)
    lib("node_estimate", node, x, P)
    return x, P.reshape(3, 3)


def test_late_measurement_replay_and_retrodict_agree(built, tmp_path):
    """One late measurement with drops in between: retrodiction is exact, so it equals replay (both
    with the Brunovsky predictor, the only one retrodiction takes), and replay equals processing
    the measurement on time (the held predictor's replay too)."""
    replay = Lib(shared_library(built("dc-brunovsky"), tmp_path), "dc_motor_link")
    retro_dir = tmp_path / "retro"
    retro_dir.mkdir()
    retro = Lib(shared_library(built("dc-retro-ci"), retro_dir), "dc_motor_link")
    on_time = _run_late(replay, 0, drops=(30, 35))
    for lag in (6, 1):
        drops = (30, 33, 35) if lag == 6 else (30, 35, 38)
        xr, Pr = _run_late(replay, lag, drops)
        xo, Po = _run_late(retro, lag, drops)
        # retrodiction and replay are algebraically equal; they round differently through an
        # A^-N back-propagation and a solve on a well-conditioned 3x3 (cond(P) ~1e4 at most), so
        # 1e-9 is n cond eps times ~100 steps of accumulation with margin, on any IEEE machine
        np.testing.assert_allclose(xo, xr, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(Po, Pr, rtol=1e-9, atol=1e-15)
    held_dir = tmp_path / "held"
    held_dir.mkdir()
    held = Lib(shared_library(built("dc-double"), held_dir), "dc_motor_link")
    for lib, first in ((replay, on_time), (held, _run_late(held, 0, drops=(30, 35)))):
        xr, Pr = _run_late(lib, 6)
        # replay re-runs exactly the on-time operations in the same order: equal up to a few ulps
        np.testing.assert_allclose(xr, first[0], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(Pr, first[1], rtol=1e-12, atol=1e-18)


def _run_scheduled(lib: Lib, late_lag: int, deliver: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The arm's scheduled node over 40 steps, σ swinging over ±0.8 rad (Φ(σ) far from Φ₀), the
    frame of step 39 - late_lag dropped and, `deliver`, given at step 39 with that lag."""
    node, late = lib.new("node"), 39 - late_lag
    assert lib("node_init", node, np.zeros(6), np.diag([1e-2, 1e-1, 1.0] * 2), np.diag([1e-4, 2e-4]).ravel(),
               np.array([10.0, 20.0])) == 0
    for k in range(40):
        z = np.array([0.3 * np.sin(0.05 * k), 0.2 * np.cos(0.07 * k)])
        measured = k not in (30, 35) and not (late_lag and k == late)
        assert lib("node_update", node, z, int(measured)) == 0
        if k == 39 and late_lag and deliver:
            z_late = np.array([0.3 * np.sin(0.05 * late), 0.2 * np.cos(0.07 * late)])
            assert lib("node_update_delayed", node, z_late, ctypes.c_int32(late_lag)) == 0
        if k < 39:
            w = np.array([np.sin(0.3 * k), np.cos(0.2 * k), 0.8 * np.sin(0.4 * k), -0.8 * np.cos(0.25 * k)])
            assert lib("node_predict", node, w) == 0
    x, P = np.zeros(6), np.zeros(36)
    lib("node_estimate", node, x, P)
    return x, P.reshape(6, 6)


def test_scheduled_replay_equals_on_time(built, tmp_path):
    """The scheduled node keeps each step's σ and P prior: a frame 6 steps late, replayed through
    six different Φ(σ), gives what it gave on time (the same operations in the same order: a few
    ulps), while without it the estimate differs (so the check can fail)."""
    lib = Lib(shared_library(built("arm-double-scheduled"), tmp_path), "two_link_arm")
    on_time = _run_scheduled(lib, 0)
    xr, Pr = _run_scheduled(lib, 6)
    np.testing.assert_allclose(xr, on_time[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(Pr, on_time[1], rtol=1e-12, atol=1e-18)
    xm, Pm = _run_scheduled(lib, 6, deliver=False)
    assert np.max(np.abs(Pm - on_time[1])) > 1e-3 * np.max(np.abs(on_time[1]))


def test_master_difference_and_control_match_numpy(built, tmp_path):
    lib = Lib(shared_library(built("dc-brunovsky"), tmp_path), "dc_motor_link")   # A, B in closed form
    flat = _flat("dc_motor_link")
    A, B, _ = flat.discrete(flat.model.ts)
    q = np.array([2.0])
    Q = flat.process_noise(flat.model.ts, q)
    master = lib.new("master")
    x0, P0 = np.array([0.1, 0.0, 0.0]), np.diag([1e-2, 1e-1, 1.0])
    assert lib("master_init", master, x0, P0.ravel().copy(), q) == 0
    v = np.array([0.5])
    assert lib("master_predict", master, v) == 0
    xm, Pm = A @ x0 + B @ v, A @ P0 @ A.T + Q
    rng = np.random.default_rng(3)
    packets = (ctypes.c_char * (2 * lib.c.dc_motor_link_packet_size()))()
    psize = lib.c.dc_motor_link_packet_size()
    Ysum, ysum = np.linalg.inv(Pm), np.linalg.solve(Pm, xm)
    for i in range(2):
        node = lib.new("node")
        assert lib("node_init", node, x0, P0.ravel().copy(), np.array([1e-4 * (i + 1)]), q) == 0
        assert lib("node_update", node, np.zeros(1), 0) == 0
        assert lib("node_predict", node, v) == 0
        z = np.array([0.1 + 0.01 * rng.standard_normal()])
        assert lib("node_update", node, z, 1) == 0
        pk = lib.new("packet")
        assert lib("node_packet", node, pk) == 0
        ctypes.memmove(ctypes.addressof(packets) + i * psize, pk, psize)
        x, P = np.zeros(3), np.zeros(9)
        lib("node_estimate", node, x, P)
        P = P.reshape(3, 3)
        Pp = A @ P0 @ A.T + Q
        Ysum += np.linalg.inv(P) - np.linalg.inv(Pp)
        ysum += np.linalg.solve(P, x) - np.linalg.solve(Pp, A @ x0 + B @ v)
    assert lib("master_fuse", master, packets, np.ones(2, dtype=np.uint8)) == 0
    x, P = np.zeros(3), np.zeros(9)
    lib("master_estimate", master, x, P)
    P_ref = np.linalg.inv(Ysum)
    # the C fuses in information form and inverts Ysum by Cholesky, numpy by LU: both backward
    # stable, so they differ by ~2 n cond(Ysum) eps; cond < 1e6 (checked) bounds it by 7e-10 < 1e-8
    assert np.linalg.cond(Ysum) < 1e6
    np.testing.assert_allclose(P.reshape(3, 3), P_ref, rtol=1e-8)
    np.testing.assert_allclose(x, P_ref @ ysum, rtol=1e-8, atol=1e-12)

    # control: v from flags and gains, u = G^-1 (v - F)
    lam = np.array([5.0])
    gains = np.zeros(3)
    assert lib("gains", lam, gains) == 0
    np.testing.assert_allclose(gains, [15.0, 75.0, 125.0])
    flags = np.array([0.2, 0.1, -0.3, 0.7])
    params = flat.param_vector.copy()
    u, vv = np.zeros(1), np.zeros(1)
    saturated = np.zeros(1, dtype=np.uint32)
    assert lib("control", x, flags, gains, params, u, vv, saturated) == 0
    assert saturated[0] == 0  # dc_motor_link declares no voltage limits: nothing is clamped
    e = x - flags[:3]
    e[0] = wrap(e[0])
    v_ref = flags[3] - gains[2] * e[0] - gains[1] * e[1] - gains[0] * e[2]
    u_ref = (v_ref - flat.F_num(x)[0]) / flat.G_num(x)[0, 0]
    # v: 3 products and sums of O(1) numbers (a few ulps); u divides by G = k_e/(J L) = 5000 after
    # F's ~30 flops with cancellation up to 100x, so 1e-10 for u on any IEEE machine
    np.testing.assert_allclose(vv, [v_ref], rtol=1e-12)
    np.testing.assert_allclose(u, [u_ref], rtol=1e-10)


def test_ci_weights_on_simplex(built, tmp_path):
    """CI on two identical packets and one different: stays consistent (no singular Hessian)."""
    lib = Lib(shared_library(built("dc-retro-ci"), tmp_path), "dc_motor_link")
    master = lib.new("master")
    P0 = np.diag([1e-2, 1e-1, 1.0])
    assert lib("master_init", master, np.zeros(3), P0.ravel().copy(), np.array([1.0])) == 0
    psize = lib.c.dc_motor_link_packet_size()
    packets = (ctypes.c_char * (2 * psize))()
    for i, r in enumerate((1e-4, 1e-4)):
        node = lib.new("node")
        assert lib("node_init", node, np.zeros(3), P0.ravel().copy(), np.array([r]), np.array([1.0])) == 0
        assert lib("node_update", node, np.array([0.05]), 1) == 0
        pk = lib.new("packet")
        lib("node_packet", node, pk)
        ctypes.memmove(ctypes.addressof(packets) + i * psize, pk, psize)
    assert lib("master_fuse", master, packets, np.ones(2, dtype=np.uint8)) == 0
    x, P = np.zeros(3), np.zeros(9)
    lib("master_estimate", master, x, P)
    node_x, node_P = np.zeros(3), np.zeros(9)
    lib("node_estimate", node, node_x, node_P)
    # CI of identical estimates is that estimate
    # CI with weights summing to 1 of identical (Y, y): an inversion round trip of a 3x3 with
    # cond(P) < 1e5, i.e. ~2 n cond eps = 7e-11 relative, below 1e-9 on any IEEE machine
    np.testing.assert_allclose(P, node_P, rtol=1e-9)
    np.testing.assert_allclose(x, node_x, rtol=1e-9)


@pytest.mark.parametrize("variant, nodes, trials", [("dc-ci3", 3, 40), ("dc-ci16", 16, 8)])
def test_ci_weights_match_reference_active_set(built, tmp_path, variant, nodes, trials):
    """M nodes (3 of them, or 16 with 3 packets absent), random informations (some far worse,
    so weights hit 0 and the active set works): the C's weights, read back as w = Y x from
    packets with y_i = Y_i x_i (x_i's angle head on the master's branch; one entry per present
    node; 16 nodes > n = 3, so x is a sum), equal
    the reference's covariance_intersection_weights with the master's iteration count."""
    from dfeif_codegen.constants import ci_iterations
    from dfeif_codegen.reference.fusion import covariance_intersection_weights
    lib = Lib(shared_library(built(variant), tmp_path), "dc_motor_link")
    psize = lib.c.dc_motor_link_packet_size()
    rng = np.random.default_rng(11)
    for trial in range(trials):
        present = np.ones(nodes, dtype=np.uint8)
        if nodes > 3:
            present[rng.choice(nodes, 3, replace=False)] = 0
        Ys = []
        for i in range(nodes):
            a = rng.normal(size=(3, 3))
            Ys.append((a @ a.T + 0.1 * np.eye(3)) * (10.0 ** rng.uniform(-2, 2)))
        used = [i for i in range(nodes) if present[i]]
        w_ref = covariance_intersection_weights([Ys[i] for i in used], ci_iterations(nodes))
        probes = rng.normal(size=(nodes, 3))   # y_i of node i: fused y = sum_i w_i y_i
        master = lib.new("master")
        assert lib("master_init", master, np.zeros(3), np.eye(3).ravel().copy(), np.array([1.0])) == 0
        packets = (ctypes.c_char * (nodes * psize))()
        for i, Y in enumerate(Ys):
            P = np.linalg.inv(Y)
            P = (P + P.T) / 2  # node_init takes only an exactly symmetric P0 (inv leaves ulp asymmetry)
            pk = lib.new("packet")
            assert lib("node_packet", _fake_node(lib, P @ probes[i], P), pk) == 0
            ctypes.memmove(ctypes.addressof(packets) + i * psize, pk, psize)
            # the master takes the angle head on the branch nearest its prior 0 (whole turns)
            x_i = P @ probes[i]
            x_i[0] = angles.wrap_np(x_i[0])
            probes[i] = Y @ x_i
        assert lib("master_fuse", master, packets, present) == 0
        x, P = np.zeros(3), np.zeros(9)
        lib("master_estimate", master, x, P)
        y = np.linalg.solve(P.reshape(3, 3), x)
        Yf = sum(w * Ys[i] for w, i in zip(w_ref, used))
        # the fused information and vector with the reference's weights: both sides take the same
        # Newton steps, the C with the Hessian in Gram form (docs/algorithms.md), so they differ by
        # rounding amplified by the steps' conditioning (|dw| <= |dg| / rho): 1e-8 relative
        np.testing.assert_allclose(P.reshape(3, 3), np.linalg.inv(Yf), rtol=1e-8, err_msg=str(trial))
        np.testing.assert_allclose(y, sum(w * probes[i] for w, i in zip(w_ref, used)), rtol=1e-8,
                                   atol=1e-8 * np.abs(probes).max(), err_msg=str(trial))


def _fake_node(lib: Lib, x: np.ndarray, P: np.ndarray):
    """A node at step 0 whose estimate is (x, P): init with that prior and a dropped update."""
    node = lib.new("node")
    assert lib("node_init", node, x.copy(), P.ravel().copy(), np.array([1.0]), np.array([1.0])) == 0
    assert lib("node_update", node, None, 0) == 0
    return node


def test_discrete_constants_match_discretize():
    """The kernels' closed-form A_d(t) for a symbolic t equals discretize's A_d at t = N Ts."""
    import casadi as ca

    from dfeif_codegen.codegen.kernels.chains import Chains
    flat = _flat("two_link_arm")
    b = Chains(flat, Options(ts=0.01))
    t = ca.SX.sym("t")
    f = ca.Function("f", [t], [b.A_of(t), b.Q_of(ca.DM([2.0, 3.0]), t)])
    for N in (1, 7, -5):
        A_got, Q_got = (np.array(m) for m in f(N * 0.01))
        # A_d entries are t^k/k! computed by the same few multiplications: at most 2-3 ulps apart
        np.testing.assert_allclose(A_got, flat.discrete(N * 0.01)[0], rtol=1e-14)
        if N > 0:
            np.testing.assert_allclose(Q_got, discretize.process_noise(flat.degrees, N * 0.01, [2.0, 3.0]),
                                       rtol=1e-13)


def test_replay_from_checkpoints_equals_reference(tmp_path):
    """A replay node keeps P priors at checkpoints (every 4th step) and recomputes the others
    (docs/algorithms.md, node storage). Window 6: the lag-6 frames start from the slot furthest
    from its checkpoint at every offset mod 4, and need the flags of steps before the window.
    Each dropped step's frame comes back late (lag 6 or 2), over 60 steps: the C equals the numpy
    reference filter. The same update formula on a 3x3 in both: rounding differs by a few ulps
    per step and the filter is contracting, so 1e-11 relative holds on any IEEE machine."""
    from dfeif_codegen.check import harness
    from dfeif_codegen.reference.node import NodeFilter

    md = harness.build_model("dc_motor_link", tmp_path / "b", "double", "replay", "difference", 2, 6)
    lib = Lib(shared_library(md.path, tmp_path), "dc_motor_link")
    flat = _flat("dc_motor_link")
    x0, P0, R, q = np.array([0.1, 0.0, 0.0]), np.diag([1e-2, 1e-1, 1.0]), np.array([[1e-4]]), np.array([5.0])
    ref = NodeFilter(flat, flat.model.ts, q, R, x0, P0, max_lag=6, oosm="replay")
    node = lib.new("node")
    assert lib("node_init", node, x0.copy(), P0.ravel().copy(), R.ravel().copy(), q.copy()) == 0
    z = {k: np.array([0.1 + 0.2 * np.sin(0.07 * k) + 0.003 * np.cos(2.3 * k)]) for k in range(60)}
    dropped, late = lambda k: k % 3 != 0 or k % 7 == 0, 0
    for k in range(60):
        gamma = int(not dropped(k))
        ref.update(z[k], bool(gamma))
        assert lib("node_update", node, z[k], gamma) == 0
        for lag in (6, 2):   # the even dropped steps come back 6 steps late, the odd ones 2
            if k >= lag and dropped(k - lag) and (k - lag) % 2 == int(lag == 2):
                assert ref.update_delayed(z[k - lag], lag)
                assert lib("node_update_delayed", node, z[k - lag], ctypes.c_int32(lag)) == 0
                late += 1
        x, P = np.zeros(3), np.zeros(9)
        assert lib("node_estimate", node, x, P) == 0
        np.testing.assert_allclose(x, ref.x, rtol=1e-11, atol=1e-14)
        np.testing.assert_allclose(P.reshape(3, 3), ref.P, rtol=1e-11, atol=1e-18)
        v = np.array([np.cos(0.1 * k)])
        ref.predict(v)
        assert lib("node_predict", node, v) == 0
    assert late > 20


WRAP_SHIM = """#include "dc_motor_link_internal.h"
void wrap_all(const real* e, real* out, int n);
void wrap_all(const real* e, real* out, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        out[i] = dc_motor_link_wrap(e[i]);
    }
}
"""


@pytest.mark.parametrize("variant, dtype", [("dc-double", np.float64), ("dc-float", np.float32)])
def test_wrap_is_the_formula_bit_for_bit(built, tmp_path, variant, dtype):
    """The node's angle wrap (a shortcut for e in (-pi, pi]) gives the bits of the reference's
    (dfeif_codegen/angles.py, fmod and one exact correction) in the build's precision, on both
    sides of 3, of pi and of every multiple of pi up to 9 pi (one ulp either side), on signed
    zeros, tiny and huge values and a dense grid; non-finite inputs give NaN, as fmod does.
    (tests/test_angles.py checks the range and exactness to 3e38 and 1e308.)"""
    cc = tool("gcc")
    src = tmp_path / "wrap.c"
    src.write_text(WRAP_SHIM)
    so = tmp_path / "libwrap.so"
    run([cc, "-std=c99", "-O2", "-fPIC", "-shared", "-I", built(variant), src, "-lm", "-o", so])
    lib = ctypes.CDLL(str(so))
    edges = [dtype(3), dtype(np.pi)] + [dtype(k * np.pi) for k in range(2, 10)]
    e = np.concatenate([np.linspace(-30, 30, 20001, dtype=dtype), [0.0, -0.0, 1e-30, -1e-30, 1e30, -1e30]]
                       + [np.nextafter(np.array([x, x, -x, -x], dtype), np.array([0, 99, 0, -99], dtype))
                          for x in edges] + [np.array(edges, dtype), -np.array(edges, dtype)]).astype(dtype)

    def wrapped(values: np.ndarray) -> np.ndarray:
        out = np.zeros_like(values)
        lib.wrap_all(values.ctypes.data_as(ctypes.c_void_p), out.ctypes.data_as(ctypes.c_void_p),
                     ctypes.c_int(values.size))
        return out

    want = angles.wrap_np(e)
    assert want.dtype == dtype and np.array_equal(wrapped(e).view(np.uint8), want.view(np.uint8))
    assert np.all(np.isnan(wrapped(np.array([np.inf, -np.inf, np.nan], dtype))))


def test_float_update_keeps_a_precise_measurements_variance(built, tmp_path):
    """A measurement 1e6 times more precise than the prior (R / P_hh = 1e-12): the float node's
    measured variance is R P_hh / (P_hh + R) to float rounding. Computed as P_hh - K_h P_hh it
    would cancel to 0 (K_h rounds to 1); the node computes that row as R K' (algorithms.md, the
    posterior covariance): K_h and R K_h round once each, so 4 eps32 = 4.8e-7 relative holds on
    any IEEE machine. The whole P equals the double reference's within 1e-5 of sigma_i sigma_j
    (a few float roundings per entry, eps32 = 6e-8, of a posterior whose correlation matrix has
    condition number below 10, checked), and stays positive definite over 50 such steps."""
    from dfeif_codegen.check import loader
    from dfeif_codegen.reference.node import NodeFilter

    lib = loader.load(built("dc-float"), cache=tmp_path / "cache")
    flat = _flat("dc_motor_link")
    G = np.array([[1.0, 0.0, 0.0], [1.0, 3.0, 0.0], [1.0, 2.0, 9.0]])
    P0, R, q, x0 = G @ G.T, np.array([[1e-12]]), np.array([20.0]), np.zeros(3)
    node = lib.Node(x0, P0, R, q)
    ref = NodeFilter(flat, flat.model.ts, q, R, x0, P0)
    z = np.array([1e-6])
    node.update(z, 1)
    ref.update(z, True)
    P = node.estimate()[1].astype(float)
    P_hh, R_hh = float(np.float32(P0[0, 0])), float(np.float32(R[0, 0]))
    assert P[0, 0] == pytest.approx(R_hh * P_hh / (P_hh + R_hh), rel=4.8e-7, abs=0)
    sigma = np.sqrt(np.diag(ref.P))
    assert np.linalg.cond(ref.P / np.outer(sigma, sigma)) < 10
    assert np.max(np.abs(P - ref.P) / np.outer(sigma, sigma)) < 1e-5
    for k in range(50):
        node.predict(np.array([0.1]))
        node.update(np.array([1e-6 * np.cos(k)]), 1)
        np.linalg.cholesky(node.estimate()[1].astype(float))


def test_float_master_keeps_its_prior_when_the_packets_bring_no_information(built, tmp_path):
    """The difference rule's finish with no information gained (D = 0, dy = 0: every node still
    waiting for its first measurement, or dropped): P = P_prior and x = c. The prior here is a
    chain's nearly collinear one, its correlation matrix's condition number above 1e4: inverting it
    and inverting back, as the finish did, lost cond * eps32 (a user model's float master was
    1.7e-4 from the reference at its second step). In the prior's factor, P = L (I + 0)^-1 L' is
    L L' with L = chol(P_prior): Cholesky's backward error and the product's rounding bound each
    entry's error by 2 (n + 1) eps32 sqrt(P_ii P_jj) (|L||L'| <= sqrt(P_ii P_jj) entrywise by
    Cauchy-Schwarz), on any IEEE machine. x = c + P 0 is c exactly."""
    lib = shared_library(built("dc-float"), tmp_path)
    n, eps32 = 3, float(np.finfo(np.float32).eps)
    B = np.array([[1.0, 0.0, 0.0], [1.0, 0.03, 0.0], [1.0, 0.05, 0.02]]) * np.array([[0.02], [0.05], [1.0]])
    Pc = (B @ B.T).astype(np.float32).astype(float)
    sigma = np.sqrt(np.diag(Pc))
    assert np.linalg.cond(Pc / np.outer(sigma, sigma)) > 1e4
    c = np.array([0.3, -1.2, 5.0])
    args = [Pc.ravel(), np.zeros(n * (n + 1) // 2), np.zeros(n), c]
    outs = [np.zeros(n), np.zeros(n * n), np.zeros(2 * n)]
    arrays = [np.ascontiguousarray(a, dtype=np.float32) for a in args + outs]
    assert lib.dc_motor_link_kern_fuse_finish(*[a.ctypes.data_as(ctypes.c_void_p) for a in arrays]) == 0
    x, P = arrays[4].astype(float), arrays[5].astype(float).reshape(n, n)
    assert np.array_equal(x, c.astype(np.float32).astype(float))
    assert np.max(np.abs(P - Pc) / np.outer(sigma, sigma)) <= 2 * (n + 1) * eps32


def test_spd_inverse_once_equals_numpy():
    """The node's information inverse (one division per column, each distinct entry once) against
    numpy's inverse and Cholesky pivots, n = 2..10. Random SPD matrices with cond < 1e3 (checked):
    two backward-stable inversions differ by at most ~2 n cond eps = 2.2e-12 relative on any IEEE
    machine, so 1e-10 holds whatever LAPACK kernel numpy picks."""
    import casadi as ca

    from dfeif_codegen.codegen.kernels import linalg
    rng = np.random.default_rng(13)
    for n in range(2, 11):
        G = rng.standard_normal((n, n))
        S = G @ G.T + n * np.eye(n)
        assert np.linalg.cond(S) < 1e3
        X = ca.SX.sym("S", n, n)
        Y, piv = linalg.spd_inverse_once(X)
        Y_got, piv_got = (np.array(v) for v in ca.Function("f", [X], [Y, piv])(S))
        np.testing.assert_allclose(Y_got, np.linalg.inv(S), rtol=1e-10, atol=1e-12, err_msg=f"n = {n}")
        assert np.array_equal(Y_got, Y_got.T)          # one expression per distinct entry
        np.testing.assert_allclose(piv_got.ravel(), np.diag(np.linalg.cholesky(S)) ** 2, rtol=1e-10)


def test_looped_kernels_equal_the_straight_line_ones(tmp_path, monkeypatch):
    """node_predict and info of a chain of 8 integrators printed as loops (kernels.LOOP_OPS at 0,
    as a chain of 13 or more gets them) and as straight-line code, double and float: x1 and the Cholesky
    pivots are the same operations in the same order, so bit-equal (without -ffp-contract, which
    the library's flags leave at its ISO default, off); P1 sums the same products in another order
    (each entry of A P A' two sums of at most 8 products, A's rows summing to at most 1.01 here:
    2 * 8 * 1.01^2 eps relative to max|P|, checked at 1e-13 in double and 1e-5 in float, where
    eps = 6e-8); Y and y come from substitutions instead of L^-1 (cond(P) < 100, checked:
    2 n cond eps = 4e-13 double, 1e-4 float, with margin at 1e-11 and 1e-3 of max|Y|, max|y|)."""
    from dfeif_codegen.check import bench_peers
    from dfeif_codegen.codegen import kernels

    n = 8
    spec = tmp_path / "chain8.toml"
    spec.write_text(bench_peers.chain_model(n))
    rng = np.random.default_rng(11)
    G = rng.standard_normal((n, n))
    P = G @ G.T + 4 * n * np.eye(n)
    assert np.linalg.cond(P) < 100
    x, c = rng.standard_normal(n), rng.standard_normal(n)
    post = np.concatenate([x, [P[i, j] for j in range(n) for i in range(j + 1)]])
    for precision, dtype, tol in (("double", np.float64, (1e-13, 1e-11)), ("float", np.float32, (1e-5, 1e-3))):
        got = {}
        for loop_ops in (0, 10 ** 6):
            monkeypatch.setattr(kernels, "LOOP_OPS", {**kernels.LOOP_OPS, "node_predict": loop_ops, "info": loop_ops})
            folder = tmp_path / f"{precision}{loop_ops}"
            mod = build.build(str(spec), folder, precision=precision, predictor="brunovsky")   # loops: Brunovsky's
            lib = shared_library(mod.path, folder)
            args = [a.astype(dtype) for a in (post, np.array([0.3]), np.array([2.0]), np.zeros(n),
                                              np.zeros(n * (n + 1) // 2), x, P.ravel(), c, np.zeros(n * n),
                                              np.zeros(n), np.zeros(n))]
            ptr = [a.ctypes.data_as(ctypes.c_void_p) for a in args]
            assert lib.chain8_kern_node_predict(*ptr[:5]) == 0
            assert lib.chain8_kern_info(*ptr[5:]) == 0
            got[loop_ops == 0] = [args[i].astype(float) for i in (3, 4, 8, 9, 10)]
        (x1, P1, Y, y, piv), (x1s, P1s, Ys, ys, pivs) = got[True], got[False]
        assert np.array_equal(x1, x1s) and np.array_equal(piv, pivs), precision
        for a, b, t in ((P1, P1s, tol[0]), (Y, Ys, tol[1]), (y, ys, tol[1])):
            np.testing.assert_allclose(a, b, rtol=0, atol=t * np.abs(b).max(), err_msg=precision)
        assert not np.array_equal(P1, P1s)   # the looped code did run


def test_filter_kernels_of_a_long_chain(tmp_path):
    """A flat chain of 7 integrators (any user model), whose info is printed as loops (above its
    kernels.LOOP_OPS operations): the master's predict, a call of node_predict on packed copies,
    equals CasADi's own evaluation of the unshared predict expression: each entry of A P A' is
    two sums of at most 7 products in either, A's rows sum to at most 1.01 here, so the two
    differ by at most 2 * 7 * 1.01^2 eps max|P| = 3.2e-15 max|P1| (max|P1| >= max|P|, as A's
    diagonal is 1 and Q >= 0), within 1e-13 max|P1| on any IEEE machine; both halves of P1 equal;
    the info kernel equals numpy's inverse (cond < 1e3 checked: 2 n cond eps = 3e-12, hence
    1e-10)."""
    from dfeif_codegen.check import bench_peers, harness
    from dfeif_codegen.codegen import kernels
    from dfeif_codegen.codegen.kernels import node
    from dfeif_codegen.codegen.kernels.chains import Chains

    n = 7
    spec = tmp_path / "chain7.toml"
    spec.write_text(bench_peers.chain_model(n))
    md = harness.build_model(str(spec), tmp_path / "b", predictor="brunovsky")   # its node_predict is looped
    lib = Lib(shared_library(md.path, tmp_path), "chain7")
    rng = np.random.default_rng(7)
    G = rng.standard_normal((n, n))
    P = G @ G.T + n * np.eye(n)
    assert np.linalg.cond(P) < 1e3
    x, v, q = rng.standard_normal(n), np.array([0.3]), np.array([2.0])
    x1, P1 = np.zeros(n), np.zeros(n * n)
    assert lib("kern_predict", x, P.ravel().copy(), v, q, x1, P1) == 0
    b = Chains(flatness.derive(model.load(str(spec))), Options(ts=0.01, predictor="brunovsky"))
    x1_ref, P1_ref = (np.array(a) for a in node.predict(b, "p")(x, P, v, q))
    ks = kernels.build(b.flat, b.opts, "chain7")
    assert set(ks.loops) & {f.name() for f in ks.groups["filter"]} == {"chain7_kern_info"}
    np.testing.assert_allclose(x1, x1_ref.ravel(), rtol=1e-13)
    np.testing.assert_allclose(P1.reshape(n, n), P1_ref, rtol=0, atol=1e-13 * np.abs(P1_ref).max())
    assert np.array_equal(P1.reshape(n, n), P1.reshape(n, n).T)
    c = rng.standard_normal(n)
    Y, y, piv = np.zeros(n * n), np.zeros(n), np.zeros(n)
    assert lib("kern_info", x, P.ravel().copy(), c, Y, y, piv) == 0
    np.testing.assert_allclose(Y.reshape(n, n), np.linalg.inv(P), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(y, np.linalg.solve(P, x - c), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(piv, np.diag(np.linalg.cholesky(P)) ** 2, rtol=1e-10)


def test_looped_fusion_kernels_equal_the_straight_line_ones(tmp_path, monkeypatch):
    """The master's kernels of a chain of 8 integrators printed as loops (kernels.LOOP_OPS at 0,
    as long chains get them: kernels.fusion_loops) and as straight-line code, difference and
    paper rules, double and float, Brunovsky builds (which also advance stale packets), on
    random SPD matrices: the loops do the straight-line code's operations in its order, each
    sum from its first product (advance's also add the exact zeros of A(N Ts) and Q_d between
    chains, none for one chain), so every output is bit-equal (without -ffp-contract, which the
    library's flags leave at its ISO default, off)."""
    from dfeif_codegen.check import bench_peers
    from dfeif_codegen.codegen import kernels

    n, npk = 8, 8 * 9 // 2
    spec = tmp_path / "chain8.toml"
    spec.write_text(bench_peers.chain_model(n))
    rng = np.random.default_rng(12)
    G = rng.standard_normal((n, n))
    P = G @ G.T + n * np.eye(n)
    Pp = P + np.diag(rng.uniform(0.5, 2.0, n))
    x, xp, c, dy = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    H = rng.standard_normal((n, n))
    Yp = H @ H.T + n * np.eye(n)   # a fused information, packed rows
    Y = np.array([Yp[i, j] for i in range(n) for j in range(i, n)])
    dY = 0.1 * Y
    fused = ("master_gain", "master_info", "fuse_finish", "fuse_finish_difference", "advance")
    for precision, dtype in (("double", np.float64), ("float", np.float32)):
        for rule in ("difference", "paper"):
            got = {}
            for loop_ops in (0, 10 ** 6):
                monkeypatch.setattr(kernels, "LOOP_OPS", {**kernels.LOOP_OPS, **{k: loop_ops for k in fused}})
                folder = tmp_path / f"{precision}{rule}{loop_ops}"
                mod = build.build(str(spec), folder, precision=precision, fusion=rule, predictor="brunovsky")
                text = (folder / "chain8_kernels_fusion.c").read_text() if (folder / "chain8_kernels_fusion.c").exists() \
                    else next(folder.rglob("chain8_kernels_fusion.c")).read_text()
                lib = shared_library(mod.path, folder)
                if rule == "difference":
                    calls = [("master_gain", [x, P.ravel(), xp, Pp.ravel(), c], [npk, n, 2 * n]),
                             ("fuse_finish", [P.ravel(), dY, dy, c], [n, n * n, 2 * n])]
                else:
                    calls = [("master_info", [x, P.ravel(), c], [npk, n, n]),
                             ("fuse_finish", [Y, dy, c], [n, n * n, n])]
                calls.append(("advance", [np.array([5.0]), x, P.ravel(), dy, np.array([2.0])], [n, n * n]))
                out = []
                for kern, ins, sizes in calls:
                    args = [a.astype(dtype) for a in ins] + [np.zeros(k, dtype) for k in sizes]
                    assert getattr(lib, f"chain8_kern_{kern}")(*[a.ctypes.data_as(ctypes.c_void_p) for a in args]) == 0
                    out += [a.astype(float) for a in args[len(ins):]]
                    # the build at 0 prints every one of them as loops, the other none
                    body = text.split(f"int chain8_kern_{kern}(")[1].split("\n}\n")[0]
                    assert ("for (" in body) == (loop_ops == 0), (kern, loop_ops)
                got[loop_ops == 0] = out
            for a, b in zip(got[True], got[False]):
                assert np.all(np.isfinite(a)) and np.array_equal(a, b), (precision, rule)


@pytest.mark.parametrize("model_name, n, opts", [("chain10", 10, {}), ("two_link_arm", 6, {}),
                                               ("two_link_arm", 8, {"disturbance": "gauss_markov", "tau": 0.5})])
def test_looped_held_predictions_equal_the_straight_line_ones(tmp_path, monkeypatch, model_name, n, opts):
    """The held predictor's node_predict, node_predict_P and the master's predict (node_predict on
    packed copies) printed as loops over parts (kernels.held.node_predict_loop) and as
    straight-line code, double and float: a chain of 10 integrators, looped by default (its
    covariance's operations above kernels.LOOP_OPS["held_covariance"]; E upper triangular), and
    two_link_arm with the limit at 0 (two chains, E's rows coupled by the held law: other bands),
    also with Gauss-Markov disturbance states (8 states, q of 4 densities).
    The mean is the same expressions either way, so x1 is bit-equal (no -ffp-contract in the
    library's flags); each entry of E P E' sums the straight line's products, in its order where
    CasADi keeps E's rows as they are (measured bit-equal on the chain and two_link_arm), else in
    another: each of two evaluations of (E P E')_ij, nested sums of at most n products, is within
    2 n u (|E| |P| |E|')_ij <= 2 n u |E|_inf^2 max|P| of the exact value (u the unit roundoff,
    first order), and the addition of Q0 (kern_noise's of the nq densities, the same array in
    both) adds u max|P1|, where in the sum it falls moving it by at most (nq + 1) u max|P1|
    (the bound when Q0 was summed as its nq terms): the bound checked."""
    from dfeif_codegen.check import bench_peers
    from dfeif_codegen.codegen import kernels
    from dfeif_codegen.symbolic import sampling

    spec = "two_link_arm"
    if model_name.startswith("chain"):
        spec = str(tmp_path / f"{model_name}.toml")
        Path(spec).write_text(bench_peers.chain_model(n))
    flat = flatness.derive(model.load(spec))
    m, nq, npk = flat.m, flat.m * (2 if opts else 1), n * (n + 1) // 2   # a disturbance per chain
    rng = np.random.default_rng(25)
    G = rng.standard_normal((n, n))
    P = G @ G.T + n * np.eye(n)
    x, u, q, centre = rng.standard_normal(n), rng.standard_normal(m), rng.uniform(0.5, 2.0, nq), rng.standard_normal(m)
    Pp = np.array([P[i, j] for j in range(n) for i in range(j + 1)])
    default = kernels.LOOP_OPS["held_covariance"]
    for precision, dtype in (("double", np.float64), ("float", np.float32)):
        got = {}
        for limit in (None, 10 ** 9) if model_name.startswith("chain") else (0, 10 ** 9):
            limit_ops = default if limit is None else limit
            monkeypatch.setattr(kernels, "LOOP_OPS", {**kernels.LOOP_OPS, "held_covariance": limit_ops})
            folder = tmp_path / f"{precision}{limit}"
            mod = build.build(spec, folder, precision=precision, **opts)
            text = next(Path(mod.path).glob("*_kernels_filter.c")).read_text()
            lib = Lib(shared_library(mod.path, folder), flat.model.name)
            Q = np.zeros(npk, dtype)
            assert lib("kern_noise", q.astype(dtype), Q) == 0
            calls = [("kern_node_predict", [np.concatenate([x, Pp]), u, Q, centre], [n, npk]),
                     ("kern_node_predict_P", [Pp, Q], [npk]),
                     ("kern_predict", [x, P.ravel(), u, Q, centre], [n, n * n])]
            out = []
            for kern, ins, sizes in calls:
                args = [a.astype(dtype) for a in ins] + [np.zeros(k, dtype) for k in sizes]
                assert lib(kern, *args) == 0
                out += [a.astype(float) for a in args[len(ins):]]
            looped = f"{flat.model.name}_kern_node_predict_bot0(" in text
            assert looped == (limit != 10 ** 9), (precision, limit)   # the default loops the chain
            got[looped] = out
        E = np.abs(sampling.held_sampling(flat, flat.model.ts, disturbance=Options(
            ts=flat.model.ts, **opts).disturbance_states()).E)
        u_r = np.finfo(dtype).eps / 2
        for k, (a, b) in enumerate(zip(got[True], got[False])):
            assert np.all(np.isfinite(a)), precision
            if k in (0, 3):   # x1 of node_predict and predict
                assert np.array_equal(a, b), precision
            else:
                tol = u_r * (4 * n * np.abs(E).sum(axis=1).max() ** 2 * np.abs(P).max() + (nq + 1) * np.abs(b).max())
                np.testing.assert_allclose(a, b, rtol=0, atol=tol, err_msg=precision)
