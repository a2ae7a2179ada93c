"""`codegen network`: nodes, master, relay and plant as separate processes on 127.0.0.1. The
reference replayed on the arrivals the relay logged must equal the programs' estimates and
inputs (double: 1e-10 relative, the bound `codegen verify` uses; measured ~1e-13), and the faults
(bit errors, a node killed and restarted, the master killed and restarted) must be survived
within bounded time, each with its own check."""

from __future__ import annotations

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.check import verify
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.net import run

KEY = "00112233445566778899aabbccddeeff"
# Every process and the launcher have deadlines; a run of 1-2 simulated seconds takes 10-30 s
# wall on a loaded 2-core machine. The launcher raises if the plant does not finish in time.


@pytest.fixture(scope="module")
def runs(tmp_path_factory, host_cc):
    cache = {}

    def get(name: str, **kw) -> run.Outcome:
        if name not in cache:
            cache[name] = run.launch(run.Options(**kw), tmp_path_factory.mktemp(name))
        return cache[name]
    return get


def z_scores(out: run.Outcome, steps: dict, lo: int = 0) -> np.ndarray:
    """|estimate - truth| / sigma per state, for the logged steps >= lo (truth from the plant)."""
    zeta = out.plant["zeta"]
    return np.array([np.abs(r[1] - zeta[k]) / np.sqrt(np.diag(r[2])) for k, r in steps.items() if k >= lo])


def test_run_equals_reference_on_logged_arrivals(runs):
    out = runs("plain", duration=2.0)
    errors, rec = run.compare(out)
    print(verify.table(errors))
    assert all(e.ok for e in errors), verify.table(errors)
    assert out.returncodes == {name: 0 for name in out.returncodes}
    K, M = out.steps, out.setup.nodes
    # every datagram is logged on receipt; camera frames follow the scenario's seeded draws exactly
    sends = [e for e in out.relay if e["ev"] == "send"]
    assert sum(e["kind"] == "camera" for e in sends) == M * K
    assert sum(e["kind"] == "packet" for e in sends) == M * K
    assert sum(e["kind"] == "command" for e in sends) == K
    assert np.array_equal(rec.gamma == 1, out.setup.net.lag[:, :K] == 0)
    lags = out.setup.net.lag[:, :K]
    due = sum(int(np.sum((lags[i] > 0) & (np.arange(K) + lags[i] < K))) for i in range(M))
    assert len(rec.late_step) == due
    # the result as data: the comparison table and the figures in its JSON
    import json
    doc = json.loads(run.Network(out, run.figures(out), errors, "summary").to_json())
    assert doc["ok"] and doc["figures"]["steps"] == K and doc["figures"]["datagrams"] == len(sends)
    assert [(e["signal"], e["worst"], e["step"]) for e in doc["errors"]] == \
        [(e.signal, float(e.worst), int(e.step)) for e in errors]


def test_keyed_run_other_model_equals_reference(runs):
    """Any flat model: two_link_arm (two chains), every frame tagged with SipHash-2-4."""
    out = runs("keyed-arm", model="two_link_arm", duration=1.0, key=KEY)
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)
    assert out.master["counters"]["R"]["accepted"] == out.setup.nodes * out.steps
    assert sum(v for k, v in out.master["counters"]["R"].items() if k != "accepted") == 0


def test_float_run_equals_reference(runs):
    """Single precision: the C's estimates within `codegen verify`'s float bounds (1e-4 of their
    scale, u and v 1e-3) of the double reference on the same arrivals."""
    out = runs("float", duration=1.0, precision="float")
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)


def test_bit_flips_rejected_counted_and_rest_equal_reference(runs):
    out = runs("flips", duration=2.0, flip_rate=1e-4)
    corrupted = sum(1 for e in out.relay if e.get("corrupt"))
    counts = out.master["counters"]["R"]
    # 1e-4 per bit on 1920-bit packets: ~17% of the 400 packets corrupted. CRC-32 misses a random
    # corruption with probability 2^-32, so every one must be refused as a CRC failure.
    assert 20 < corrupted < 150
    assert counts["crc"] == corrupted and counts["accepted"] == 2 * out.steps - corrupted
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)


def test_node_killed_and_restarted(runs):
    out = runs("node-restart", duration=2.0, faults=(run.Fault(1, 60, 90),), step_timeout=0.05)
    assert out.returncodes == {name: 0 for name in out.returncodes}
    assert out.master["events"] == [(1, "silent", 59), (1, "rejoined", 90)]
    restarted = out.nodes[1]
    assert restarted["counters"]["joined"] == 90 and sorted(restarted["steps"]) == list(range(90, out.steps))
    assert sorted(out.nodes[1]["first"]["steps"]) == list(range(60))
    srcs = [row["src"][1] for k, row in sorted(out.master["steps"].items())]
    assert all(s == -1 for s in srcs[61:90]) and sum(s >= 90 for s in srcs[90:]) > 50
    # consistency bounds (independent of the C): every estimate within 5 sigma of the true state;
    # the restarted node starts from the initial prior, so it is held to that 20 steps after joining
    master = {k: (None, r["x"], r["P"]) for k, r in out.master["steps"].items()}
    assert z_scores(out, master).max() < 5
    assert z_scores(out, restarted["steps"], 110).max() < 5


def test_master_restarted(runs):
    out = runs("master-restart", duration=2.0, faults=(run.Fault("master", 60, 90),), command_timeout=0.1)
    assert out.returncodes == {name: 0 for name in out.returncodes}
    for node in out.nodes:     # the nodes kept filtering through the outage, predicting with the last v
        assert sorted(node["steps"]) == list(range(out.steps))
        assert node["counters"]["H"]["held"] == 30
        assert z_scores(out, node["steps"]).max() < 5
    assert out.master["counters"]["joined"] == 90
    assert sorted(out.master["steps"]) == list(range(90, out.steps))
    master = {k: (None, r["x"], r["P"]) for k, r in out.master["steps"].items()}
    assert z_scores(out, master).max() < 5
    assert int(out.plant["got"].sum()) == out.steps - 30


def test_network_api_refuses_bad_options_before_building(tmp_path, host_cc):
    """The keyword API checks its options first: nothing is built or written for a bad one."""
    keep = tmp_path / "keep"
    for kw, words in [({"key": "abc"}, "--key 'abc'"), ({"flip_rate": 1.0}, "--flip-rate 1.0"),
                      ({"row": 99}, "--row 99")]:
        with pytest.raises(ScenarioError, match=words):
            run.network(duration=0.5, keep=keep, **kw)
        assert not keep.exists()


def test_cli_network_passes_and_rejects_bad_input(capsys, host_cc):
    assert cli.main(["network", "--duration", "0.5", "--seed", "3"]) == 0
    text = capsys.readouterr().out
    assert "PASS" in text and "packet 240 B" in text
    assert cli.main(["network", "--row", "99"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--row 99" in err
    assert cli.main(["network", "--key", "abc"]) == 2
