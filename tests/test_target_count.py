"""Counting on the emulated Cortex-M4F (check/target_count.py): exact and deterministic on loops
whose instruction count is known by construction, a cycle estimate that follows the documented
table, and a stack figure that includes newlib's frames."""

from __future__ import annotations

import pytest

from conftest import require_tool
from dfeif_codegen.check import target_count

pytestmark = pytest.mark.target

# `spin(n)` is hand-written assembly: n turns of (subs, bne) then bx lr, so 2 n + 1 instructions;
# the compiler cannot change that. `twice` calls spin twice around a known frame.
SPIN = r"""
#include "target_mark.h"
#include <math.h>
#include <stdio.h>
__attribute__((noinline, naked)) void spin(unsigned n)
{
    __asm volatile("1: subs r0, r0, #1\n\tbne 1b\n\tbx lr\n");
}
__attribute__((noinline)) void twice(unsigned n)
{
    volatile unsigned pad[30];
    pad[0] = n;
    spin(pad[0]);
    spin(n);
}
int main(void)
{
    static const unsigned ns[] = {1, 7, 100, 1000};
    char name[32];
    for (int i = 0; i < 4; i++) {
        for (int r = 0; r < 3; r++) {
            CALLGRIND_TOGGLE_COLLECT;
            spin(ns[i]);
            CALLGRIND_TOGGLE_COLLECT;
        }
        snprintf(name, sizeof name, "spin%u:3", ns[i]);
        CALLGRIND_DUMP_STATS_AT(name);
    }
    volatile float big = 1e6f;
    float s = sinf(big);   /* sinf's large-argument path */
    twice(3);
    printf("s %g\n", (double)s);
    return 0;
}
"""


@pytest.fixture(scope="module")
def spin_elf(tmp_path_factory):
    for tool, pkg in (("arm-none-eabi-gcc", "gcc-arm-none-eabi"), ("qemu-system-arm", "qemu-system-arm")):
        require_tool(tool, pkg)
    work = tmp_path_factory.mktemp("spin")
    src = work / "spin.c"
    src.write_text(SPIN)
    return target_count.program([], src, [], work / "build"), work


def test_known_loop_counts_exactly_and_the_same_twice(spin_elf):
    elf, work = spin_elf
    first, _ = target_count.count(elf, work)
    second, _ = target_count.count(elf, work)
    assert first == second
    for n in (1, 7, 100, 1000):
        sec = first[f"spin{n}"]
        assert sec["instructions"] == 2 * n + 1 and sec["max"] == 2 * n + 1
        # by the table: subs 1; bne taken (n - 1 times) 1 + P, not taken once 1; bx lr 1 + P
        for P, cycles in zip(target_count.REFILL, sec["cycles"]):
            assert cycles == n + (n - 1) * (1 + P) + 1 + (1 + P)


def test_mnemonics_map_to_the_table():
    cases = {"ble.n": "b", "bl": "b" + "l", "vadd.f32": "vadd", "addeq": "add", "movs": "mov",
             "ldmia.w": "ldmia", "vmla.f32": "vmla", "itte": "it", "vldr": "vldr", "blt.w": "b",
             "subs.w": "sub", "vcvt.f32.s32": "vcvt", "lsls": "lsl"}
    assert {m: target_count.base_mnemonic(m) for m in cases} == cases


def test_stack_includes_newlib_frames(spin_elf):
    elf, _ = spin_elf
    table = target_count.disassemble(elf)
    frame, _ = target_count.frames(table, target_count.operands(elf))
    use = target_count.stack_with_library(elf, ["twice", "main", "sinf"], table)
    # twice: its own frame (30 words of pad at least) plus spin's, which has none
    assert use["twice"][0] == frame["twice"] >= 120 and use["twice"][1] == ("twice", "spin")
    # main reaches sinf, whose large-argument reduction has frames of its own below it
    assert use["sinf"][0] > frame["sinf"] and use["main"][0] >= frame["main"] + use["sinf"][0]


def test_peers_on_the_target_agree_and_rank(tmp_path):
    """The peers program on the emulated Cortex-M4F (float, -Os): bench_target.peer_counts raises
    unless each peer ends where the generated filter does; the hand-written filter executes fewer
    instructions than the generated one, the dense loops more, and the cycle estimate brackets
    at least one cycle per instruction (every entry of the table is >= 1 but IT's low figure)."""
    require_tool("qemu-system-arm", "qemu-system-arm")
    from dfeif_codegen.check import bench_target
    from dfeif_codegen.check.bench_measure import measure

    out = bench_target.peer_counts(measure(bench_target.compile_peers("dc_motor_link", tmp_path)))
    assert out["straight"]["instructions"] < out["generated"]["instructions"] < out["dense"]["instructions"]
    for peer in out.values():
        lo, hi = peer["cycles"]
        assert 0.9 * peer["instructions"] <= lo <= hi
