"""`codegen bench`'s comparisons: the synthetic chains, the growth fit and the C peers."""

from __future__ import annotations

import numpy as np

from conftest import require_tool
from dfeif_codegen.check import bench_peers, harness
from dfeif_codegen.check.bench_measure import measure
from dfeif_codegen.codegen.options import Options
from dfeif_codegen.symbolic import flatness, model as model_mod


def _chain(n: int, folder):
    path = folder / f"chain{n}.toml"
    path.write_text(bench_peers.chain_model(n))
    return path


def test_synthetic_chain_is_flat_with_relative_degree_n(tmp_path):
    for n in (2, 5, 10):
        path = tmp_path / f"chain{n}.toml"
        path.write_text(bench_peers.chain_model(n))
        flat = flatness.derive(model_mod.load(str(path)))
        assert flat.degrees == [n] and flat.n == n


def test_growth_fit_recovers_a_power_law():
    sizes = np.array([2.0, 3.0, 5.0, 8.0, 13.0])
    # exact in exact arithmetic; the least-squares fit of 5 logs is good to ~1e-14
    assert abs(bench_peers.growth(sizes, 7.0 * sizes ** 2.25) - 2.25) < 1e-12


def test_chain_rows_give_each_n_its_ratio_to_the_previous_one():
    """The scaling tables' shared rows (host and Cortex-M4F): n in order, thousands separated, the
    ratio to the previous n to two decimals, then the table's own cells."""
    ch = {8: {"step": 12345, "t": 7}, 2: {"step": 1000, "t": 3}, 4: {"step": 2500, "t": 5}}
    assert bench_peers.chain_rows(ch, lambda c: (c["t"], "x")) == [
        "| 2 | 1,000 | - | 3 | x |", "| 4 | 2,500 | 2.50 | 5 | x |", "| 8 | 12,345 | 4.94 | 7 | x |"]


def test_c_peers_give_the_generated_filters_estimate(host_cc, tmp_path):
    """The compare step (bench_peers.checked) raises unless the dense-loop and the straight-line filters end where the generated
    filter ends after 200 steps (1e-9), each with the generated filter's predictor (held: the
    ETD2RK mean calling the model function, E P E' + Q; brunovsky: the linear chain); the
    straight-line one exists for the 3-state motor only."""
    require_tool("valgrind", "valgrind")
    for pred in bench_peers.PREDICTORS:
        md = harness.build_model("dc_motor_link", tmp_path / f"b{pred}", **bench_peers.with_predictor(pred))
        assert md.options.get("predictor") == pred
        out = bench_peers.checked(measure(bench_peers.peers("dc_motor_link", md, tmp_path / f"w{pred}")))
        assert set(out["instructions"]) == set(out["ns"]) == {"generated", "dense", "straight"}
        # the hand-written straight-line filter and the generated one do the same arithmetic, the
        # generated one checking its inputs besides: within 2x of each other (measured with gcc 12
        # -O2: held 621 / 628, both adding a Q formed before the run; Brunovsky 320 / 202, whose
        # hand-written chain folds A_d's ones and zeros by hand); the dense loops multiply zeros too
        ins = out["instructions"]
        assert 0 < ins["straight"] < ins["dense"] and ins["generated"] < ins["dense"], ins
        assert ins["generated"] < 2 * ins["straight"], ins
    arm = harness.build_model("two_link_arm", tmp_path / "a")
    assert set(bench_peers.checked(measure(bench_peers.peers("two_link_arm", arm, tmp_path / "wa")))["instructions"]) \
        == {"generated", "dense"}


def test_kernel_text_splits_the_filter_object_by_kernel(tmp_path):
    """check.kernel_text's per-kernel bytes (nm symbol sizes) add up to the object's .text as
    arm-none-eabi-size counts it (each kernel is its own section: nothing else is in it), the
    replay build's four filter kernels, the static parts of looped kernels (n = 8) counted with
    their kernel; the master's predict, a call of node_predict on packed copies, is smaller than
    node_predict itself once n > 2."""
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    from dfeif_codegen.check import kernel_text

    for n in (2, 4, 8):
        per, text = kernel_text.chain_kernels(n, tmp_path)
        assert set(per) == {"predict", "node_predict", "update", "info"}
        assert sum(per.values()) == text
    assert per["predict"] < per["node_predict"]


def test_worst_case_counts_every_public_entry_point(host_cc, tmp_path):
    """bench_stages.worst_case measures each function the public header declares (read from the header,
    not from the harness), and the costliest calls are the long paths: a frame back at lag
    N_max replays the window, stale packets over a last fused packet N_max steps old cost the
    master more than fresh ones."""
    import re

    from dfeif_codegen.check import bench_stages

    require_tool("valgrind", "valgrind")
    worst = {}
    for predictor in ("held", "brunovsky"):
        md = harness.build_model("dc_motor_link", tmp_path / predictor, predictor=predictor)
        worst[predictor] = measure(bench_stages.worst_case(md, tmp_path / f"w-{predictor}"))
        header = (md.path / "dc_motor_link.h").read_text()
        declared = set(re.findall(r"^(?:int|size_t|uint32_t|uint64_t) dc_motor_link_(\w+)\(", header, re.M))
        assert set(worst[predictor]) == declared
        fuse, late, step = (worst[predictor][f] for f in ("master_fuse", "node_update_delayed", "node_update"))
        assert fuse["max"] > fuse["median"]
        assert late["max"] > 16 * step["max"]      # 33 steps of the window replayed
    # Brunovsky: a stale packet is brought forward in one step (one A P A' per estimate, plus one
    # 3-vector step per stored input): two packets 32 steps old cost a few times a fresh fuse;
    # stepped one prediction at a time they cost 26 times (measured, 39,001 vs 1,474 instructions)
    fuse = worst["brunovsky"]["master_fuse"]
    assert fuse["max"] < 5 * fuse["median"]
    # held: its mean is not linear, so each estimate is stepped once per stored input: per packet
    # (2) the last one fused from its node over 32 (the lost packets' channel, worst.c.j2) and its
    # x and x_pred over 30; never more than one master prediction per step on top of a fresh fuse
    fuse, predict = worst["held"]["master_fuse"], worst["held"]["master_predict"]
    assert fuse["median"] < fuse["max"] < fuse["median"] + 2 * (32 + 2 * 30) * predict["max"], (fuse, predict)


def test_looped_filter_kernels_grow_as_n_squared(tmp_path):
    """On chains of 7 integrators and more, info is a loop over parts of O(n^2) straight-line code
    (kernels.LOOP_OPS), node_predict stays straight-line (the per-step kernel, up to 2,500
    operations): info's Cortex-M4F .text from n = 7 to 10 grows by less than (10/7)^2 = 2.04
    (lower-order terms only lower the ratio); its straight-line code, Theta(n^3) bytes, grew by 3.3."""
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    from dfeif_codegen.check import kernel_text
    from dfeif_codegen.codegen import kernels

    flat = flatness.derive(model_mod.load(str(_chain(7, tmp_path))))
    # the Brunovsky predictor's node_predict stays straight-line up to LOOP_OPS["node_predict"]
    ks = kernels.build(flat, Options(ts=flat.model.ts, predictor="brunovsky"), "chain7")
    assert set(ks.loops) & {f.name() for f in ks.groups["filter"]} == {"chain7_kern_info"}
    size = {}
    for n in (7, 10):
        per, _ = kernel_text.chain_kernels(n, tmp_path)
        size[n] = per["info"]
    assert size[10] / size[7] < (10 / 7) ** 2


def test_looped_held_node_predict_grows_as_n_squared(tmp_path):
    """The default (held) build's node_predict and node_predict_P are loops from a chain of 10
    integrators on (kernels.LOOP_OPS["held_covariance"]; 9 stays straight-line): parts of O(n^2)
    code each (E times a column, a band of its rows; P unpacked; P1 packed plus Q0; the mean),
    O(1) loops and calls, so their Cortex-M4F .text from n = 10 to 12 grows by less than
    (12/10)^2 = 1.44 (lower-order terms only lower the ratio; 1.37 measured), where the
    straight-line code, Theta(n^3) bytes, grew by 1.72."""
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    from dfeif_codegen.check import kernel_text
    from dfeif_codegen.codegen import kernels

    looped = {}
    for n in (9, 10):
        flat = flatness.derive(model_mod.load(str(_chain(n, tmp_path))))
        ks = kernels.build(flat, Options(ts=flat.model.ts), f"chain{n}")
        looped[n] = {k for k in ks.loops if "node_predict" in k}
    assert looped == {9: set(), 10: {"chain10_kern_node_predict", "chain10_kern_node_predict_P"}}
    size = {n: kernel_text.chain_kernels(n, tmp_path / "k", predictor=None)[0]["node_predict"] for n in (10, 12)}
    assert size[12] / size[10] < (12 / 10) ** 2


def test_looped_fusion_kernels_grow_as_n_squared(tmp_path):
    """The master's kernels of the default build (difference rule: master_gain, fuse_finish) are
    loops from n = 7 (kernels.LOOP_OPS, kernels.fusion_loops), each around one sum written out:
    O(n^2) code (per inversion n(n-1)/2 + (n-1)(n-2)/2 + n(n-1)/2 products, plus O(n) loops and
    O(1) glue), where the straight-line code's Theta(n^3) operations are Theta(n^3) bytes. So
    their Cortex-M4F .text from n = 7 to 10 grows by less than (10/7)^2 = 2.04: the leading
    terms' ratio is 2.1, the O(n) and O(1) code brings it below (1.8 measured); straight-line
    it grew by 3.2."""
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    from dfeif_codegen.check import kernel_text
    from dfeif_codegen.codegen import kernels

    flat = {n: flatness.derive(model_mod.load(str(_chain(n, tmp_path)))) for n in (6, 7)}
    looped = {n: set(kernels.build(f, Options(ts=f.model.ts), f"chain{n}").loops) - {f"chain{n}_kern_info"}
              for n, f in flat.items()}   # info, a filter kernel, is looped from n = 7 too
    assert looped == {6: set(), 7: {"chain7_kern_master_gain", "chain7_kern_fuse_finish"}}
    size = {n: kernel_text.chain_kernels(n, tmp_path, "fusion", None)[1] for n in (7, 10)}
    assert size[10] / size[7] < (10 / 7) ** 2


def test_c_peers_take_the_models_mean_substeps(host_cc, tmp_path):
    """A model whose mean takes three ETD2RK steps per period ([model] mean_substeps): both
    hand-written peers loop their mean over the shorter step's constants and still end where the
    generated filter ends after 200 steps (the compare step's 1e-9); with one step per period
    they would not (the motor's one-step error is 1e-7 of a period's change on θ'')."""
    require_tool("valgrind", "valgrind")
    text = model_mod.builtin_text("dc_motor_link")
    assert "\nts = 0.01\n" in text
    path = tmp_path / "motor3.toml"
    path.write_text(text.replace("\nts = 0.01\n", "\nts = 0.01\nmean_substeps = 3\n"))
    md = harness.build_model(str(path), tmp_path / "b")
    out = bench_peers.checked(measure(bench_peers.peers(str(path), md, tmp_path / "w")))
    assert set(out["instructions"]) == {"generated", "dense", "straight"}
