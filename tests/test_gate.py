"""The innovation gate (`codegen build --gate G`): a node refuses a measurement whose innovation e
has e' S^-1 e > G^2 (S its covariance), on time and late, leaving its state unchanged.

The expectations are independent of the code under test: the threshold from the definition on
the C node's own prior (a numpy oracle), the C's decisions and estimates against the Python
reference's (reference/node.py), and the reference's refusals against the same recording without
the gate.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dfeif_codegen import OutlierError, build, derive, load, load_model
from dfeif_codegen.check import harness, verify
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import scenario
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.reference.node import NodeFilter

GATE = 4.0


@pytest.fixture(scope="module")
def motor(tmp_path_factory):
    """dc_motor_link with the gate, loaded through the public API."""
    return load(build("dc_motor_link", tmp_path_factory.mktemp("gate"), gate=3.0))


def _started(lib, steps: int = 5):
    """A node after `steps` on-time updates and predictions, at the prior of the next step."""
    n, ny = lib.nx, lib.ny
    node = lib.Node(np.zeros(n), np.eye(n) * 1e-2, np.eye(ny) * 1e-6, np.ones(lib.nq))
    for _ in range(steps):
        node.update(np.zeros(ny))
        node.predict(np.zeros(lib.nu))
    return node


def test_the_gate_refuses_exactly_beyond_its_threshold_and_changes_nothing(motor):
    """3 standard deviations of S = P_HH + R, S taken from the C node's prior: z at 2.999 sigma is
    used, at 3.001 sigma refused with ERR_OUTLIER, the node's bytes unchanged but the outlier
    counter; the step then goes on without it. The 1e-3 margin is far above the rounding of
    e' S^-1 e (a few ulps of double)."""
    heads = list(derive(load_model("dc_motor_link")).heads)
    x, P = _started(motor).estimate()
    sigma = float(np.sqrt(P[heads[0], heads[0]] + 1e-6))
    inside, outside = _started(motor), _started(motor)
    inside.update(x[heads] + 2.999 * sigma)
    assert inside.health()["updates"] == 6 and inside.health()["outliers"] == 0
    before = np.frombuffer(bytes(outside._state), np.uint8)
    with pytest.raises(OutlierError):
        outside.update(x[heads] + 3.001 * sigma)
    changed = np.nonzero(np.frombuffer(bytes(outside._state), np.uint8) != before)[0]
    assert outside.health()["outliers"] == 1 and outside.health()["updates"] == 5
    assert changed.size and changed[-1] - changed[0] < 4   # one uint32: the counter, nothing else
    outside.update(None, 0)   # the step goes on without the measurement
    outside.predict(np.zeros(motor.nu))
    assert outside.health()["drops"] == 1


def test_the_gate_refuses_a_finite_absurd_measurement(motor):
    """1e300 rad is finite: without a gate it would be folded in (a posterior of about 1e299); with
    one it is refused and the node goes on."""
    node = _started(motor)
    x0, _ = node.estimate()
    with pytest.raises(OutlierError):
        node.update(np.full(motor.ny, 1e300))
    node.update(None, 0)
    x1, _ = node.estimate()
    assert np.array_equal(x0, x1)


def _with_outliers(rec, size: float = 200.0):
    """The recording with every 23rd on-time measurement of node 0 and every 3rd late one moved
    by `size` camera standard deviations (sqrt R): outliers far outside any 4-sigma gate."""
    z, late_z = np.array(rec.z), np.array(rec.late_z)
    sd = np.sqrt(np.diagonal(rec.R, axis1=1, axis2=2))   # (nodes, ny)
    on_time = [k for k in np.nonzero(rec.gamma[0])[0] if k % 23 == 11]
    z[0, on_time] += size * sd[0]
    late = np.arange(0, len(late_z), 3)
    late_z[late] += size * sd[np.asarray(rec.late_node)[late]]
    return dataclasses.replace(rec, z=z, late_z=late_z, gate=GATE), on_time, late


@pytest.mark.parametrize("oosm", ["replay", "retrodict"])
def test_c_and_reference_refuse_the_same_measurements(tmp_path, monkeypatch, oosm):
    """A recorded closed loop with outliers injected, on time and late: the reference with the
    gate refuses every injected late frame the reference without it applied, and the C built
    with --gate equals the reference with it to 1e-10 (every estimate, and which late frames were
    applied, exactly). Every decision the reference took is at least 1e-6 (relative) from the
    threshold, so the C's rounding (1e-10 of the reference) cannot flip one."""
    rec = verify.record("dc_motor_link", oosm=oosm, duration=2.0)
    gated, on_time, late = _with_outliers(rec)
    seen: list[float] = []
    refused = NodeFilter._refused

    def spy(self, e, S):
        if self.gate is not None:
            seen.append(float(e @ np.linalg.solve(S, e)))
        return refused(self, e, S)

    monkeypatch.setattr(NodeFilter, "_refused", spy)
    # the filters predict with their own controller's inputs, which the outputs then record:
    # the C with the recorded inputs predicts with the same
    want = ex.replay_recording(gated)
    free = ex.replay_recording(dataclasses.replace(gated, gate=0.0))
    assert on_time and len(late) > 0 and seen
    assert np.min(np.abs(np.array(seen) / GATE ** 2 - 1)) > 1e-6
    applied_free, applied = np.asarray(free["late_applied"]), np.asarray(want["late_applied"])
    assert applied_free[late].any() and not applied[late].any()
    # the gate changed the estimates (node 0's on-time outliers were refused)
    assert not np.allclose(free["node_x"][0], want["node_x"][0])
    expected = dataclasses.replace(gated, **want)
    module = build("dc_motor_link", tmp_path / "c", gate=GATE, oosm=oosm)
    library = harness.Library(harness.ModelDir.open(module.path), tmp_path / "lib")
    verify.check(verify.compare_run(library.run(expected, "recorded"), expected, "double"))


def test_verify_builds_and_records_with_the_gate():
    """`codegen verify --gate 2`: the paper scenario's closed loop with the gate refuses good
    frames (a 2-sigma gate refuses about 4.6% of a consistent filter's), and the C built with it
    equals that reference. A refusal the C and the reference could decide differently needs a
    d^2 within the C's rounding (1e-10 relative) of 4: about 1e-11 per frame for a chi-square
    density of 0.03 there, so none in the run's 4,000 frames."""
    res = verify.closed_loop("dc_motor_link", row=verify.verify_row(scenario.load("paper")), gate=2.0)
    assert sum(c["outliers"] for c in res.counters) > 20
    result = verify.verify("dc_motor_link", gate=2.0)
    assert result.ok and "gate 2" in result.settings


def _loop(**kw) -> ex.Config:
    """A short closed loop with late frames, camera outliers on both nodes (2% of the frames,
    40 camera sigma) and, unless told, the nodes' gate."""
    base = dict(model="dc_motor_link", duration=3.0, q=(20.0,), poles=(10.0,), metrics_from=0.5, seed=5,
                sensor=(Link(0.8, 6), Link(0.8, 8)), outliers=((0.02, 40.0), (0.02, 40.0)), gate=GATE)
    return ex.Config(**{**base, **kw})


def test_outliers_move_only_the_frames_they_hit():
    """A scenario's camera outliers are added to the noise the cameras draw, from a stream of their
    own: the noise of every other frame is the outlier-free run's bit for bit, and a hit frame's
    moves by exactly the size on every channel."""
    clean, hit = ex.prepare(_loop(outliers=())), ex.prepare(_loop())
    for a, b in zip(clean.noise, hit.noise):
        moved = np.any(a != b, axis=1)
        assert 0 < moved.sum() < len(moved) // 10
        np.testing.assert_array_equal(a[~moved], b[~moved])
        np.testing.assert_allclose(np.abs(b[moved] - a[moved]), 40.0, rtol=1e-12)


@pytest.mark.parametrize("method", ["replay", "retrodict"])
def test_both_engines_refuse_the_same_outliers(host_cc, method):
    """The compiled loop (its library built with --gate) against the numpy one, with outliers on
    both nodes: the same counters (the refusals included) and estimates to test_engine_c's 1e-9
    (the same IEEE operations on the same draws, a few sums in another order; no refusal within
    that of the threshold in this run, or the counters would differ). The gate then keeps the
    master about as accurate as without outliers: its RMSE on theta at most 1.5x the clean run's,
    where the same outliers ungated cost more than 2x."""
    from dfeif_codegen.check import closed_loop_c

    c, py = closed_loop_c.run(_loop(method=method)), ex.run(_loop(method=method))
    assert c.counters == py.counters and sum(n["outliers"] for n in py.counters) > 5
    np.testing.assert_allclose(c.recording.x, py.recording.x, rtol=1e-9, atol=1e-12)
    clean, ungated = ex.run(_loop(method=method, outliers=())), ex.run(_loop(method=method, gate=0.0))
    rmse = lambda r: r.metrics["rmse_master"][0]  # noqa: E731
    assert rmse(py) < 1.5 * rmse(clean) and rmse(ungated) > 2 * rmse(clean)


def test_the_comparisons_filters_gate_their_frames_as_the_nodes_do():
    """`simulate --filters` on a scenario with a gate: every filter of the comparison refuses
    frames with the same test. The derivative-free filter through the comparison's driver is the
    closed loop's own (the same frames refused, the same master estimate to 1e-9: only sums in
    another order differ); the EKF and UKF refuse frames too, and gated they are at least twice as
    accurate as ungated on the same outliers."""
    from dfeif_codegen.experiment import compare

    res, free = ex.run(_loop()), ex.run(_loop(gate=0.0))
    df = compare.evaluate(res, "df")
    assert df["outliers"] == res.metrics["outliers"] > 0
    np.testing.assert_allclose(df["rmse_master"], res.metrics["rmse_master"], rtol=1e-9)
    for kind in ("ekf", "ukf"):
        gated, ungated = compare.evaluate(res, kind), compare.evaluate(free, kind)
        assert gated["outliers"] > 0 and ungated["outliers"] == 0
        assert gated["rmse_master"][0] < ungated["rmse_master"][0] / 2
