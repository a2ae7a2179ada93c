"""`verify` is three steps, each called once and in order: compile, run, compare (check/stages.py)."""

from __future__ import annotations

import dfeif_codegen as dc
from dfeif_codegen.check import stages, verify


def test_verify_compiles_runs_and_compares_once_each_in_order(monkeypatch):
    calls = []

    def spy(name, fn):
        def wrapped(*args, **kw):
            calls.append(name)
            return fn(*args, **kw)
        return wrapped

    monkeypatch.setattr(stages, "compile", spy("compile", stages.compile))
    monkeypatch.setattr(stages, "run", spy("run", stages.run))
    monkeypatch.setattr(verify, "compare_outputs", spy("compare", verify.compare_outputs))
    result = dc.verify("dc_motor_link")
    assert calls == ["compile", "run", "compare"]
    assert result.ok and {e.signal for e in result.errors} >= {"master.x", "u"}


def test_bench_compiles_runs_and_compares_once_each_in_order(monkeypatch, tmp_path, cross_tools):
    """`bench` on a model file (a 3-integrator chain, --quick, one build timing): compile, run and
    compare are each called once and in order; every code generation and compilation happens
    inside the compile step, every measurement inside the run step, and the result is the one
    the report is made of (each peer's figures, the target's worst cases, struct sizes)."""
    from conftest import require_tool
    from dfeif_codegen.check import bench_measure, bench_peers, bench_stages, harness, target

    require_tool("valgrind", "valgrind")
    calls = []

    def spy(name, fn):
        def wrapped(*args, **kw):
            calls.append(name)
            return fn(*args, **kw)
        return wrapped

    for stage in ("compile", "run", "compare"):
        monkeypatch.setattr(bench_stages, stage, spy(stage, getattr(bench_stages, stage)))
    for module, fn in ((harness, "build_model"), (harness, "compile_program"), (target, "compile_objects"),
                       (target, "link"), (target, "sizeof_probe")):
        monkeypatch.setattr(module, fn, spy("build", getattr(module, fn)))
    monkeypatch.setattr(bench_measure, "RUNNERS", {k: spy("measure", f) for k, f in bench_measure.RUNNERS.items()})
    spec = tmp_path / "chain3.toml"
    spec.write_text(bench_peers.chain_model(3))
    result = dc.bench(str(spec), repeat=1, quick=True)
    stages_called = [c for c in calls if c in ("compile", "run", "compare")]
    assert stages_called == ["compile", "run", "compare"]
    at = {name: calls.index(name) for name in stages_called}
    assert set(calls[at["compile"] + 1:at["run"]]) == {"build"}
    assert set(calls[at["run"] + 1:at["compare"]]) == {"measure"}
    assert calls[at["compare"] + 1:] == []
    (sec,) = result.sections
    assert sec["name"] == str(spec) and len(sec["times"]) == 1 and result.comparisons == {}
    # chain3's node step: the hand-written straight-line filter beats the generated one, the dense loops do not
    for pred in bench_peers.PREDICTORS:
        i = sec["peers"][pred]["instructions"]
        assert i["straight"] < i["generated"] < i["dense"]
        assert sec["target_peers"][pred]["generated"]["instructions"] > 0
    assert set(sec["target"]["stack"]) == {"replay", "retrodict"}
    assert sec["sizeof"]["double"]["node"] > sec["sizeof"]["float"]["node"]
    assert f"## {spec}" in result.report()
    # the scheduled predictor beside the held one: a chain of integrators has L(σ) = L₀, so its
    # scheduled node step costs what the held one does (Φ(σ) folds to Φ₀), within 10%
    held, sched = sec["counts"][("replay", "difference")], sec["counts"][("replay", "difference", "scheduled")]
    assert abs(sched["node_predict"] / held["node_predict"] - 1) < 0.1
    assert "| node step (update + predict) |" in result.report()
