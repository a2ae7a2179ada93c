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
