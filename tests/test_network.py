"""`codegen network`: nodes, master, relay and plant as separate processes on 127.0.0.1. The
reference replayed on the arrivals the relay logged must equal the programs' estimates and
inputs (double: 1e-10 relative, the bound `codegen verify` uses; measured ~1e-13), and the faults
(bit errors, a node killed and restarted, the master killed and restarted) must be survived
within bounded time, each with its own check."""

from __future__ import annotations

import dataclasses
import subprocess

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.check import verify
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.net import launch, run

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


def test_disturbance_states_and_model_error_run_equal_reference(runs, tmp_path_factory):
    """A scenario with disturbance states (an integrated random walk: two per chain), a plant
    whose J and R are off the model's and a see-saw reference: the programs carry the filters' five states (their frames
    sized for them, the clock's ticks for the reference's four flags), end on the plant's end
    tick, and equal the reference on the logged arrivals. The plant is the scenario's: its flat
    outputs are the in-process closed loop's on the same draws (the same commands: 1e-8 relative
    over 100 steps of a loop whose commands agree to 1e-13), and not the exact model's (which
    leaves them by more than 1e-4: the check can fail)."""
    from pathlib import Path

    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment import model_error, scenario

    path = tmp_path_factory.mktemp("scenario") / "dist.toml"
    paper = Path(scenario.__file__).with_name("scenarios").joinpath("paper.toml").read_text()
    path.write_text(paper.replace('references = ["sinusoid", "seesaw"]', 'references = ["seesaw"]')
                    + '\n[disturbance]\nkind = "integrated_random_walk"\nq = 1e5\n'
                    + '\n[model_error]\nrelative = { J = 0.2, R = -0.15 }\n')
    out = runs("disturbance", scenario=str(path), duration=1.0)
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)
    assert out.returncodes == {name: 0 for name in out.returncodes}   # the end tick was taken
    assert out.layout.n == 5 and out.layout.tick_reals == 1 + 4
    assert all(len(x) == 5 and P.shape == (5, 5) for _, x, P in out.nodes[0]["steps"].values())
    cfg = launch.make_config(out.opts)
    assert cfg.reference == "seesaw"   # the scenario's reference (it ran a sinusoid whatever the scenario said)
    zeta = out.plant["zeta"]
    own = ex.run(cfg).zeta[:len(zeta)]
    exact = ex.run(dataclasses.replace(cfg, plant_error=model_error.NONE)).zeta[:len(zeta)]
    scale = np.abs(own).max(axis=0)
    assert np.all(np.abs(zeta - own) <= 1e-8 * scale)
    assert np.max(np.abs(exact - own) / scale) > 1e-4
    assert run.figures(out)["loop"] is None     # the loop held, as simulate's watch judges it


def test_a_loop_that_diverges_is_said_so(runs, tmp_path_factory):
    """The comparison judges the C against the reference on the loop the processes closed, not
    the loop: a plant far off the model (J -90%, k_e +90%, L +95%) whose master NEES runs away
    still passes it, and the summary says what simulate's divergence watch says of that loop,
    word for word as the in-process engine's watch raises it on the same draws."""
    from pathlib import Path

    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment import scenario
    from dfeif_codegen.experiment.divergence import Diverged

    path = tmp_path_factory.mktemp("scenario") / "far.toml"
    path.write_text(Path(scenario.__file__).with_name("scenarios").joinpath("paper.toml").read_text()
                    + "\n[model_error]\nrelative = { J = -0.9, k_e = 0.9, L = 0.95 }\n")
    out = runs("diverging", scenario=str(path), duration=2.0)
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)
    with pytest.raises(Diverged) as caught:
        ex.run(launch.make_config(out.opts))
    verdict = run.figures(out)["loop"]
    assert verdict == str(caught.value) and "master NEES" in verdict
    assert f"the loop: {verdict}" in run.summary(out.opts, out, run.figures(out), run.compare(out)[1])


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


def restart_reference(out: run.Outcome, who: int, back: int):
    """The reference on the logged arrivals, node `who` started again at step `back` from the
    initial prior with its own step count (as templates/net/node_main.c.j2), the steps it
    ran read from its logs; the controller's inputs its own. Returns the master's x, P per step
    and the late frames the restarted node applied."""
    from dfeif_codegen.experiment.recording import FilterBank
    from dfeif_codegen.net import session
    from dfeif_codegen.reference.node import NodeFilter
    s, K = out.setup, out.steps
    rec = session.recording(s, out.relay, out.plant["frames"], K)
    bank = FilterBank(s.flat, rec.ts, rec.q, rec.R, rec.node_x0, rec.node_P0, rec.master_x0, rec.master_P0,
                      rec.gains, rec.max_lag, rec.oosm, rec.fusion, predictor=rec.predictor)
    ran = [set(nd["first"]["steps"]) | set(nd["steps"]) for nd in out.nodes]
    base, applied = [0] * s.nodes, 0
    late_at = np.searchsorted(rec.late_step, np.arange(K + 1))
    sources = np.full((K, s.nodes), -1)
    sources[rec.pkt_step, rec.pkt_node] = rec.pkt_src
    X, P = np.zeros((K, s.flat.n)), np.zeros((K, s.flat.n, s.flat.n))
    for k in range(K):
        if k == back:
            bank.nodes[who] = NodeFilter(s.flat, rec.ts, rec.q, rec.R[who], s.x_hat0, s.P0, max_lag=rec.max_lag,
                                         oosm=rec.oosm, predictor=rec.predictor, mid_run=True)
            base[who], bank.sent[who] = back, {}
        alive = [i for i in range(s.nodes) if k in ran[i]]
        for i in alive:
            bank.nodes[i].update(rec.z[i, k] if rec.gamma[i, k] else None, bool(rec.gamma[i, k]))
        for e in range(late_at[k], late_at[k + 1]):
            i, lag = int(rec.late_node[e]), int(rec.late_lag[e])
            if i in alive and k - lag >= base[i]:      # the program refuses frames from before its start
                ok = bank.nodes[i].update_delayed(rec.late_z[e], lag)
                applied += ok and i == who and k >= back
        for i in alive:
            bank.sent[i][k] = dataclasses.replace(bank.nodes[i].packet(), step=k)
        bank.master.fuse([bank.sent[i].get(src) if src >= 0 else None for i, src in enumerate(sources[k])])
        X[k], P[k] = bank.master.x, bank.master.P
        u, v = bank.control(bank.master.x, rec.ref[k])
        w = bank.master.predictor.input(u, v, bank.master.x)
        for i in alive:
            bank.nodes[i].predict(w)
        bank.master.predict(w)
    return X, P, applied


def test_node_killed_and_restarted(runs):
    """Node 1 killed before step 60 and started again before step 90 from the initial prior, 18
    sigma from the plant by then; the defaults (held predictor, replay, difference rule). Before
    a node started mid-run refused late frames of steps before its first measurement (its prior
    alone there: node_mid_run), its replay of step 91's frame at step 92 moved its θ by 0.89 rad,
    and the held predictor's mean over that correction, entering the difference rule as
    information, put the master's θ'' 28 sigma off (NEES 811). Now the master stays within 1.6
    sigma, and the C equals the reference given the restart."""
    out = runs("node-restart", duration=2.0, faults=(launch.Fault(1, 60, 90),), step_timeout=0.05)
    assert out.setup.cfg.predictor == "held" and out.setup.cfg.fusion == "difference"   # the defaults
    assert out.returncodes == {name: 0 for name in out.returncodes}
    assert out.master["events"] == [(1, "silent", 59), (1, "rejoined", 90)]
    restarted = out.nodes[1]
    assert restarted["counters"]["joined"] == 90 and sorted(restarted["steps"]) == list(range(90, out.steps))
    assert sorted(out.nodes[1]["first"]["steps"]) == list(range(60))
    srcs = [row["src"][1] for k, row in sorted(out.master["steps"].items())]
    assert all(s == -1 for s in srcs[61:90]) and sum(s >= 90 for s in srcs[90:]) > 50
    # the C master equals the reference given the restart (1e-10 relative, `codegen verify`'s
    # bound in double; measured 3e-14), and the node applied the same late frames
    X, P, applied = restart_reference(out, 1, 90)
    x_c = np.array([out.master["steps"][k]["x"] for k in range(out.steps)])
    P_c = np.array([out.master["steps"][k]["P"] for k in range(out.steps)])
    assert np.all(np.abs(x_c - X) <= 1e-10 * np.abs(X).max(axis=0))
    assert np.abs(P_c - P).max() <= 1e-10 * np.abs(P).max()
    assert restarted["counters"]["H"]["late_applied"] == applied > 20
    # consistency (independent of the C): a consistent estimate is N(x, P); |error| > 5 sigma in
    # one of the 3 states at one of the 200 steps has probability 200 * 3 * 5.7e-7 = 3.4e-4
    master = {k: (None, r["x"], r["P"]) for k, r in out.master["steps"].items()}
    assert z_scores(out, master).max() < 5
    # no jump at the rejoin: NEES below the chi-square(3) quantile at 1e-6 at every step from 90
    # (811 before)
    from scipy.stats import chi2
    e = x_c[90:] - out.plant["zeta"][90:out.steps]
    nees = np.einsum("ki,ki->k", e, np.linalg.solve(P_c[90:], e[..., None])[..., 0])
    assert nees.max() < chi2.isf(1e-6, 3)
    # the node itself starts 18 sigma off and forgets that prior at its own pace (its estimate
    # is not the master's; measured 5.0 sigma on 120-149, 3.2 from 160): held to the bound from 160
    assert z_scores(out, restarted["steps"], 160).max() < 5


def test_master_restarted(runs):
    out = runs("master-restart", duration=2.0, faults=(launch.Fault("master", 60, 90),), command_timeout=0.1)
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
    assert "PASS" in text and "packet 244 B" in text
    assert cli.main(["network", "--row", "99"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--row 99" in err
    assert cli.main(["network", "--key", "abc"]) == 2


def test_network_runs_a_two_row_scenario_on_its_last_row(tmp_path, capsys, host_cc):
    """The default row is the paper grid's third (index 2, (8, 10, 0.8)); a scenario with two
    rows has none there, and `network` with no --row refused it ("has rows 0..1"): it now runs
    the last row, (4, 6, 0.8), and says so."""
    from pathlib import Path

    from dfeif_codegen.experiment import scenario

    paper = Path(scenario.__file__).with_name("scenarios").joinpath("paper.toml").read_text()
    grid = paper.index("[[grid]]")
    path = tmp_path / "two_rows.toml"
    path.write_text(paper[:grid] + "[[grid]]\nd = [0, 0]\np = 0.0\n[[grid]]\nd = [4, 6]\np = 0.8\n")
    assert cli.main(["network", "--scenario", str(path), "--duration", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "row 1 seed 0" in out and "PASS" in out


def test_a_process_that_ended_early_is_named(tmp_path):
    """When a run does not finish, the message names each process that had already ended, how,
    and the last line of its stderr (a killed node was 'did not finish in time', nothing more),
    and where its logs are only when they outlive the run."""
    import signal
    import time

    dead = launch._Proc("node1", ["sh", "-c", "echo 'node 1: nothing received in time, exiting' >&2; exit 3"], tmp_path)
    killed = launch._Proc("node0", ["sleep", "30"], tmp_path)
    alive = launch._Proc("master", ["sleep", "30"], tmp_path)
    killed.p.send_signal(signal.SIGKILL)
    time.sleep(0.5)
    early = {p.name: p.ended() for p in (dead, killed, alive)}
    assert early == {"node1": 3, "node0": -9, "master": None}
    msg = launch._who_ended(early, tmp_path, kept=True)
    assert "node1 ended early (exit 3: node 1: nothing received in time, exiting)" in msg
    assert "node0 ended early (killed by signal 9)" in msg and "master" not in msg
    assert f"see {tmp_path}/*.err" in msg      # a kept folder; a temporary one is gone when the user reads this
    assert "--keep DIR keeps the logs" in launch._who_ended(early, tmp_path, kept=False)
    for p in (dead, killed, alive):
        p.reap(0)


def test_a_program_that_fails_ends_the_run_before_its_deadline(tmp_path):
    """A node that exits with an error (bad start-up values) while the plant waits for the
    step's frames ends the drive at once, not at the deadline (60 s plus 0.2 s per step: 86 s
    for a 1 s run, all spent waiting for a process that was gone)."""
    import time

    failed = launch._Proc("node0", ["sh", "-c", "echo 'node 0: bad start-up values' >&2; exit 2"], tmp_path)
    plant = launch._Proc("plant", ["sleep", "120"], tmp_path, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    finished, restarts, retired = launch._drive(launch.Options(), None, {"node0": failed}, plant, t0 + 100)
    assert not finished and restarts == {} and retired == []
    assert time.monotonic() - t0 < 50        # half the deadline: the drive polls once a second
    assert failed.ended() == 2
    for p in (failed, plant):
        p.reap(0)


def test_forged_frames_rejected_by_cause_in_the_running_programs(runs, tmp_path_factory):
    """A keyed run; at the start of a step k >= 40 an attacker who knows the frame format (and, for the
    replays and the unusable covariances, the key: what a compromised or replaying sender could
    send) sends the master one frame per rejection cause and node 0 a replayed tick, a replayed
    camera frame, a forged command and a corrupted kind byte. Each is refused and counted under
    its own cause, and the run still equals the reference (nothing forged reached a filter)."""
    import struct
    import zlib

    from dfeif_codegen.check import harness
    from dfeif_codegen.net import session, wire

    key = bytes.fromhex(KEY)
    lay = wire.Layout.of_folder(harness.build_model("dc_motor_link", tmp_path_factory.mktemp("lay") / "gen").path)
    n, m = lay.n, lay.m
    o = run.Options(duration=1.0, key=KEY)
    lag = session.setup(run.make_config(o)).net.lag
    k = next(j for j in range(40, 90) if lag[0, j - 1] == 0)   # node 0's frame of k - 1 came at once

    def packet(P_scale=1.0, pred=0.01):
        return np.concatenate([np.zeros(m), np.zeros(n), (0.005 * P_scale * np.eye(n)).ravel(), np.zeros(n),
                               (pred * np.eye(n)).ravel()])

    def enc(kind, node, step, seq, values, keyed=key, patch=()):
        b = bytearray(wire.encode(lay, kind, node, step, seq, values, keyed))
        for at, v in patch:
            b[at] = v
        if patch:
            b[-4:] = struct.pack("<I", zlib.crc32(bytes(b[:-4])))
        return bytes(b)

    fresh = 1 << 30
    bad_p = packet()
    bad_p[m + n] = -0.005
    nan_p = packet()
    nan_p[m] = np.nan
    good = enc(wire.KIND_PACKET, 0, k, fresh, packet())
    master = {
        "length": good[:-1],
        "crc": good[:30] + bytes([good[30] ^ 0x40]) + good[31:],
        "format": enc(wire.KIND_PACKET, 0, k, fresh, packet(), patch=[(5, 9)]),
        "version": enc(wire.KIND_PACKET, 0, k, fresh, packet(), patch=[(4, 1)]),
        "model": enc(wire.KIND_PACKET, 0, k, fresh, packet(), patch=[(8, good[8] ^ 1)]),
        "tag": enc(wire.KIND_PACKET, 0, k, fresh, packet(), keyed=bytes(16)),
        "nonfinite": enc(wire.KIND_PACKET, 0, k, fresh, nan_p),
        "node": enc(wire.KIND_PACKET, 7, k, fresh, packet()),
        "replay": enc(wire.KIND_PACKET, 0, k, 5, packet()),
        "future": enc(wire.KIND_PACKET, 0, k + 3, fresh, packet()),
        "old": enc(wire.KIND_PACKET, 0, k - 34, fresh, packet()),
        "duplicate": enc(wire.KIND_PACKET, 1, k - 1, fresh, packet()),
        "outdated": enc(wire.KIND_PACKET, 1, k - 2, fresh, packet()),
        "covariance": enc(wire.KIND_PACKET, 0, k, fresh, bad_p),
        "gain": enc(wire.KIND_PACKET, 0, k, fresh, packet(P_scale=3.0)),
        "epoch": wire.encode(lay, wire.KIND_PACKET, 0, k, fresh, packet(), key, epoch=1),   # not the master's boot
    }
    tick = np.zeros(1 + lay.n + lay.m)
    node0 = [enc(wire.KIND_TICK, 0, k - 1, fresh, tick),                       # a replayed tick
             enc(wire.KIND_CAMERA, 0, k - 1, fresh, np.full(m, 0.3)),   # k - 1's frame came: a replay
             enc(wire.KIND_COMMAND, wire.MASTER_ID, k - 1, fresh, np.zeros(2 * m), keyed=bytes(16)),
             enc(wire.KIND_TICK, 0, k, fresh, tick)[:5] + b"\x07" + enc(wire.KIND_TICK, 0, k, fresh, tick)[6:]]
    o.inject_at, o.inject = (k,), lambda step: [("master", f) for f in master.values()] + [(0, f) for f in node0]
    out = runs("forged", **{f.name: getattr(o, f.name) for f in dataclasses.fields(o)})
    counts = out.master["counters"]["R"]
    assert {c for c, v in counts.items() if v and c != "accepted"} == set(master)
    assert all(counts[c] == 1 for c in master), counts
    assert counts["accepted"] == out.setup.nodes * out.steps
    node = out.nodes[0]["counters"]
    assert node["H"]["replayed"] == 2
    # the forged command fails its tag; the tick with a corrupted kind byte is checked as a command:
    # its size is not a command's
    assert node["R"]["tag"] == 1 and node["R"]["length"] == 1
    errors, _ = run.compare(out)
    assert all(e.ok for e in errors), verify.table(errors)


def test_restarted_master_refuses_frames_recorded_before_it_restarted(runs, tmp_path_factory):
    """Keyed; the master is killed before step 60 and restarted (-r, its epoch 1) before step 90.
    Right after it starts, a replayer sends it node 0's and node 1's packets of steps 85-89 as
    recorded before the kill (epoch 0, their genuine sequence numbers, the key's tag); at step 95
    it sends node 0 a recorded command of epoch 0 with a sequence number above any the master
    uses. Each is refused and counted under `epoch`; the nodes' own packets of step 90, sent
    before they heard the new master, are refused alike. The master joins at step 91 from a
    genuine packet of its epoch (the nodes took its announcement at 90) and tracks the truth.
    Before: the restarted master initialised from the first replayed packet (joined at 85), and
    the replayed command's sequence number made node 0 refuse every later real command."""
    from dfeif_codegen.check import harness
    from dfeif_codegen.net import wire

    key = bytes.fromhex(KEY)
    lay = wire.Layout.of_folder(harness.build_model("dc_motor_link", tmp_path_factory.mktemp("lay") / "gen").path)
    n, m = lay.n, lay.m
    old = np.concatenate([np.zeros(m), np.full(n, 3.0), (1e-8 * np.eye(n)).ravel(), np.full(n, 3.0),
                          (1e-8 * np.eye(n)).ravel()])              # far from the truth, and sure of it
    replays = [wire.encode(lay, wire.KIND_PACKET, i, k, k, old, key, epoch=0) for k in range(85, 90) for i in (0, 1)]
    command = wire.encode(lay, wire.KIND_COMMAND, wire.MASTER_ID, 95, 1 << 30, np.full(2 * m, 5.0), key, epoch=0)

    def inject(step):
        return [("master", f) for f in replays] if step == 90 else [(0, command)]

    out = runs("master-restart-replayed", duration=1.5, key=KEY, faults=(launch.Fault("master", 60, 90),),
               command_timeout=0.1, inject_at=(90, 95), inject=inject)
    assert out.returncodes == {name: 0 for name in out.returncodes}
    counts = out.master["counters"]["R"]
    assert counts["epoch"] == len(replays) + out.setup.nodes, counts
    assert sum(v for c, v in counts.items() if c not in ("accepted", "epoch")) == 0, counts
    assert out.master["counters"]["joined"] == 91
    assert sorted(out.master["steps"]) == list(range(91, out.steps))
    master = {k: (None, r["x"], r["P"]) for k, r in out.master["steps"].items()}
    assert z_scores(out, master).max() < 5
    node0 = out.nodes[0]["counters"]
    assert node0["R"]["epoch"] == 1 and node0["R"]["replay"] == 0
    for node in out.nodes:     # held through the outage and the announcing step 90, then commanded again
        assert node["counters"]["H"]["held"] == 31
        assert z_scores(out, node["steps"]).max() < 5
    assert int(out.plant["got"].sum()) == out.steps - 31


def _bench_fig(cpus, load, median, p99, own):
    """A synthetic `codegen network --bench` measurement: only the values the text must derive from."""
    tp = {"model": "dc_motor_link", "keyed": False, "packets_per_s": 1.0, "datagrams_per_s": 1.5, "accepted": 2,
          "expected": 2, "master_cpu_us_per_datagram": 4.0, "tick_rtt_median_us": own, "tick_rtt_p99_us": own}
    nw = {"steps": 500, "wall_s": 3.0, "equal": True, "latency_median_us": median, "latency_p99_us": p99,
          "master_busy_us_per_step": 2.0, "node_busy_us_per_step": [1.0, 1.0], "cpu_s": {"master": 0.25},
          "datagrams": 10}
    return {"sizes": [], "throughput": [tp], "network": nw, "cpus": cpus, "load": load}


def test_bench_text_derives_from_what_was_measured():
    """Issue 24 finding 9: no fixed sentence about the machine; every claim follows the measured values."""
    from dfeif_codegen.net import bench

    fast = bench.markdown(_bench_fig(8, 0.5, 150.0, 900.0, 40.0))
    for fixed in ("2 cores", "shared VM", "10-25 us", "scheduling delays", "other jobs"):
        assert fixed not in fast
    assert "8 processors" in fast and "load average 0.50" in fast
    assert "Both latency targets are met." in fast and "Targets missed" not in fast
    slow = bench.markdown(_bench_fig(3, 1.0, 300.0, 3000.0, 60.0))
    # 300 us median - 60 us master round trip - (2 + 1 + 1) us C busy time = 236 us for the other hops
    assert "Targets missed: median 300 us" in slow and "remaining 236 us" in slow
    assert "10.0 times the median" in slow and "3 processors" in slow


def test_bench_network_summary_prints_no_dict_repr():
    """The `codegen network` summary writes its per-process CPU and rejection counts as text, not `{'k': v}`."""
    from types import SimpleNamespace

    lay = SimpleNamespace(size=lambda k: 8 * k, packet_reals=3, command_reals=1)
    setup = SimpleNamespace(cfg=SimpleNamespace(disturbance=None, reference="sinusoid"), plant_p=None)
    out = SimpleNamespace(steps=10, layout=lay, setup=setup)
    rec = SimpleNamespace(gamma=np.ones(4), late_step=[1], pkt_step=[1, 2])
    f = {"wall_s": 1.0, "datagrams": 30, "accepted": 20, "rejected": {"crc": 2, "stale": 1},
         "latency_median_us": 100.0, "latency_p99_us": 500.0, "master_busy_us_per_step": 2.0,
         "cpu_s": {"master": 0.125, "node0": 0.25}}
    text = run.summary(run.Options(), out, f, rec)
    assert "{" not in text and "'" not in text
    assert "rejected crc 2, stale 1" in text and "CPU: master 0.125 s, node0 0.250 s" in text
    assert "rejected none" in run.summary(run.Options(), out, {**f, "rejected": {}}, rec)
    setup.cfg.disturbance, setup.plant_p = SimpleNamespace(kind="random_walk"), np.ones(2)
    text = run.summary(run.Options(), out, f, rec)
    assert "(sinusoid) row 2 seed 0, disturbance random_walk, plant parameters as [model_error] draws them, 10 steps" \
        in text
