"""A bounded libFuzzer run (clang -fsanitize=fuzzer,address,undefined) over the wire decoder, the
master's receive/fuse path and the node API, from the committed seed corpus: no finding allowed.
60 s in CI (CI=true), 15 s elsewhere; a missing clang or fuzzer runtime fails in CI, skips elsewhere."""

from __future__ import annotations

from pathlib import Path

from conftest import IN_CI, missing, require_tool
from dfeif_codegen.check import harness
from dfeif_codegen.errors import SetupError
from dfeif_codegen.net import fuzz, wire

CORPUS = Path(__file__).parent / "fuzz_corpus"


def test_seed_corpus_is_the_generated_one(tmp_path):
    """The committed corpus is what `fuzz.seed_corpus` writes (so it stays valid for the format)."""
    md = harness.build_model("dc_motor_link", tmp_path / "gen")
    want = fuzz.seed_corpus(wire.Layout.of_folder(md.path), 32)
    assert {p.name: p.read_bytes() for p in CORPUS.iterdir() if p.is_file()} == want


def test_fuzz_bounded_run_has_no_finding(tmp_path):
    clang = require_tool("clang", "clang")
    md = harness.build_model("dc_motor_link", tmp_path / "gen")
    try:
        exe = fuzz.build(md, tmp_path / "fuzz", clang)
    except SetupError as exc:
        missing(f"{exc} (libFuzzer runtime missing: apt-get install libclang-rt-14-dev)")
    seconds = 60 if IN_CI else 15
    res = fuzz.run(exe, CORPUS, tmp_path / "work", seconds)
    print(f"fuzz: {res.executions} executions in {res.seconds:.0f} s")
    assert res.returncode == 0 and not res.findings, res.log
    assert res.executions > 1000   # the target really ran (about 4000 executions/s on one core)
