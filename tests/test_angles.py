"""The angle wrap (dfeif_codegen/angles.py, templates/internal.h.j2) stays in (-pi, pi] for every
finite input, is exact (the result differs from the input by a whole number of the precision's
2pi, checked in rational arithmetic: an independent expectation), and is the same bits in numpy,
CasADi and the generated C; a run whose camera frames carry huge angles equals the reference and
keeps its estimate (the wrap before this one left the interval from |e| ~ 1e16, 1e9 in float)."""

from __future__ import annotations

import dataclasses
import math
import subprocess
from fractions import Fraction

import casadi as ca
import numpy as np
import pytest

from conftest import Case
from dfeif_codegen import angles
from dfeif_codegen.check import harness, verify
from dfeif_codegen.experiment import closed_loop as experiment

WARN = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wdouble-promotion", "-Werror"]


def adversarial(dtype) -> np.ndarray:
    """Huge values, values beside multiples of pi and 2pi, the edges of the format, denormals,
    and 400 log-uniform magnitudes over the whole finite range."""
    f = np.finfo(dtype)
    pi, two_pi = dtype(math.pi), dtype(2 * math.pi)
    near = [np.nextafter(c, dtype(np.inf)) for c in (pi, -pi, two_pi, -two_pi)] + \
        [np.nextafter(c, dtype(-np.inf)) for c in (pi, -pi, two_pi, -two_pi)]
    fixed = [0.0, -0.0, pi, -pi, two_pi, -two_pi, 3 * pi, -3 * pi, 1e9, -1e9, 1e16, -1e16, 2.0 ** 60,
             1e30, -1e30, f.max, -f.max, f.tiny, -f.tiny, f.smallest_subnormal, 195191.0, *near]
    rng = np.random.default_rng(24)
    exps = rng.uniform(np.log10(float(f.smallest_subnormal)), np.log10(float(f.max)), 400)
    rand = np.sign(rng.uniform(-1, 1, 400)) * 10.0 ** exps
    with np.errstate(over="ignore"):
        vals = np.concatenate([np.array(fixed, dtype=dtype), rand.astype(dtype)])
    return vals[np.isfinite(vals)]


@pytest.mark.parametrize("dtype", [np.float64, np.float32], ids=["double", "float"])
def test_wrap_is_in_range_and_exact(dtype):
    e = adversarial(dtype)
    r = angles.wrap_np(e)
    assert r.dtype == dtype
    pi, two_pi = Fraction(float(dtype(math.pi))), Fraction(float(dtype(2 * math.pi)))
    assert Fraction(float(dtype(2 * math.pi))) == 2 * pi   # what the exactness argument uses
    for a, b in zip(e.tolist(), r.tolist()):
        assert -pi < Fraction(b) <= pi, (a, b)
        k = (Fraction(a) - Fraction(b)) / two_pi
        assert k.denominator == 1, (a, b)          # a whole number of turns removed, exactly
    small = (e > -dtype(math.pi)) & (e <= dtype(math.pi))
    assert np.array_equal(r[small], e[small])      # nothing to do: the value itself


def test_casadi_wrap_equals_numpy():
    x = ca.SX.sym("x")
    f = ca.Function("w", [x], [angles.wrap_sx(x)])
    e = adversarial(np.float64)
    got = np.array([float(f(v)) for v in e])
    want = angles.wrap_np(e)
    assert np.array_equal(got, want)    # bit for bit (a -0 compares equal to +0)


C_PROGRAM = """#include <stdio.h>
#include <string.h>
#include "{p}_internal.h"
int main(void)
{{
    {real} e, r;
    {uint} bits;
    while (scanf("%{fmt}", &bits) == 1) {{
        memcpy(&e, &bits, sizeof(e));
        r = {p}_wrap(e);
        memcpy(&bits, &r, sizeof(r));
        printf("%{fmt}\\n", bits);
    }}
    return 0;
}}
"""


@pytest.mark.parametrize("precision", ["double", "float"])
def test_c_wrap_equals_reference(tmp_path, host_cc, precision):
    """The generated `<model>_wrap` under the strict flags (no double promotion in float) gives the
    reference's bits for every adversarial input."""
    md = harness.build_model("dc_motor_link", tmp_path / "gen", precision)
    dtype, uint, fmt = ((np.float64, "unsigned long long", "llx") if precision == "double"
                         else (np.float32, "unsigned int", "x"))
    real = "double" if precision == "double" else "float"
    src = tmp_path / "wrap.c"
    src.write_text(C_PROGRAM.format(p=md.name, real=real, uint=uint, fmt=fmt))
    exe = tmp_path / "wrap"
    flags = [f for f in WARN if precision == "float" or f != "-Wdouble-promotion"]
    subprocess.run([host_cc, *flags, f"-I{md.path}", str(src), *map(str, md.sources()), "-lm",
                    "-o", str(exe)], check=True, capture_output=True, text=True)
    e = adversarial(dtype)
    itype = np.uint64 if precision == "double" else np.uint32
    text = "\n".join(f"{int(b):x}" for b in e.view(itype)) + "\n"
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout.split()
    got = np.array([int(s, 16) for s in out], dtype=itype).view(dtype)
    assert np.array_equal(got.view(itype), angles.wrap_np(e).view(itype))


HUGE = [Case("dc_motor_link", "replay", "difference", "sinusoid", 2, duration=3.0),
        Case("dc_motor_link", "retrodict", "ci", "seesaw", 2, duration=3.0)]
# Below 2^50 the C's centring (exact steps of 1/8, internal.h) subtracts exactly, so the C forms
# the reference's innovation bit for bit; beyond, both wrap exactly but round z - x differently.
EXACT = np.array([1e15 + 0.375, -7.5e14, 2.0 ** 49, 3e13 + 0.125, -1e12 - 0.5, 123456789.0])
HUGER = np.array([1e17, -3e18, 2.0 ** 60, -1e16 - 2.0, 3.0e38, -1.5e38])


def with_huge_angles(rec, values, current: bool = True, late: bool = True) -> experiment.Recording:
    """The recording with some camera frames (node 0's current ones spread over the first half,
    every fifth late one there) replaced by huge angles, and the outputs the reference gives."""
    z, late_z = rec.z.copy(), rec.late_z.copy()
    half = rec.ref.shape[0] // 2
    if current:
        steps = np.nonzero(rec.gamma[0, :half])[0]
        z[0, steps[np.linspace(0, len(steps) - 1, len(values)).astype(int)], 0] = values
    if late:
        early = np.nonzero(rec.late_step < half)[0][::5][:len(values) if len(values) == 1 else None]
        late_z[early, 0] = np.resize(values, early.shape)
    changed = dataclasses.replace(rec, z=z, late_z=late_z)
    return dataclasses.replace(changed, **experiment.replay_recording(changed))


def recovered(got, rec, tol: float) -> None:
    """Finite throughout, and the node and master angles back within `tol` of the undisturbed
    run (modulo whole turns: a garbage frame may move a node to another branch) over the last
    half second (the last such frame is in the first half)."""
    for key in ("x", "node_x"):
        assert np.all(np.isfinite(got[key])), key
        off = angles.wrap_np(got[key][..., -50:, 0] - getattr(rec, key)[..., -50:, 0])   # on any branch
        assert np.max(np.abs(off)) < tol, key


@pytest.mark.parametrize("case", HUGE, ids=str)
def test_huge_angles_equal_reference_and_keep_the_estimate(store, case):
    """Frames of 1e12..1e15 rad: the C equals the reference (double, 1e-10) and both recover."""
    rec = store.recording(case)
    bad = with_huge_angles(rec, EXACT)
    assert np.any(bad.z != rec.z) and len(rec.late_z) >= 5
    verify.check(verify.compare_run(store.library(case, "double").run(bad), bad, "double"))
    recovered(vars(bad), rec, 0.05)


@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("case", HUGE, ids=str)
def test_huger_angles_keep_the_estimate(store, case, precision):
    """One frame of up to 3e38 rad (beyond 2^50, where the innovation's rounding is no longer the
    reference's), a current one or a late one: the C, double or float, stays finite and
    recovers like the reference. (Several such frames can leave a node on an alias, its rate a
    whole turn per step, which the frames cannot tell from the truth; one cannot.) Before, one
    frame left the master at 195,191 rad for good."""
    rec = store.recording(case)
    lib = store.library(case, precision)
    for value in HUGER:
        for late in (False, True):
            bad = with_huge_angles(rec, np.array([value]), current=not late, late=late)
            recovered(vars(bad), rec, 0.05)
            recovered(lib.run(bad), rec, 0.05)


@pytest.mark.parametrize("rule", ["paper", "difference", "ci"])
def test_fusion_takes_angles_on_the_master_branch(tmp_path, host_cc, rule):
    """Node estimates 6.383 and 0.1 rad (the same angle: 6.383 - 2pi = 0.0998), each after one
    measurement of its own value, fuse near 0.1 in the reference and in the C, each rule: each
    node's head (x and x_pred alike) is moved by whole turns to the branch nearest the master's
    prediction. Without it the fused angle lay between the two, about pi from both."""
    import dfeif_codegen as dc
    from dfeif_codegen.reference.fusion import Master
    from dfeif_codegen.reference.node import NodeFilter
    from dfeif_codegen.symbolic import flatness

    flat = flatness.derive(dc.load_model("dc_motor_link"))
    ts = flat.model.ts
    lib = dc.load(dc.build("dc_motor_link", tmp_path / "out", fusion=rule, nodes=2), cache=tmp_path / "cache")
    P0, R, q = np.diag([1e-2, 1e-2, 1e-2]), np.array([[1e-3]]), np.array([1.0])
    starts = [np.array([6.383, 0.2, 0.0]), np.array([0.1, 0.2, 0.0])]
    master0 = np.array([0.1, 0.2, 0.0])
    c_packets, r_packets = [], []
    for x0 in starts:
        node = lib.Node(x0, P0, R, q)
        node.update([x0[0]])
        c_packets.append(node.packet())
        ref = NodeFilter(flat, ts, q, R, x0, P0)
        ref.update([x0[0]], True)
        r_packets.append(ref.packet())
    c_master = lib.Master(master0, P0, q)
    c_master.fuse(c_packets)
    r_master = Master(flat, ts, q, master0, P0, n_nodes=2, rule=rule)
    r_master.fuse(r_packets)
    for x in (c_master.estimate()[0], r_master.x):
        assert abs(x[0] - 0.1) < 1e-3, x
    assert np.allclose(c_master.estimate()[0], r_master.x, rtol=0, atol=1e-12)
