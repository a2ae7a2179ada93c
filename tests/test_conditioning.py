"""F-bar in the form single precision computes best (symbolic/conditioning.py): the flexible
joint's spring term, a difference of two nearly equal angles once Phi^-1 is substituted, is
rewritten away; a model whose substituted form loses nothing keeps it."""

from __future__ import annotations

from pathlib import Path

import sympy as sp

from dfeif_codegen.symbolic import conditioning, flatness, model

from test_user_models import FLEX_JOINT

DATA = Path(__file__).parent / "data"


def test_a_sum_is_rewritten_only_where_the_symbols_cancel():
    """x - (k x + y) / k is -y / k, shorter; (x - y)^2, x y + 1 and a quotient of sums nothing
    cancels in are kept: expanded they are as long or longer."""
    x, y, k = sp.symbols("x y k")
    assert conditioning.cancel_sums(x - (k * x + y) / k) == -y / k
    assert conditioning.cancel_sums(2 * sp.sin(x - (k * x + y) / k)) == 2 * sp.sin(-y / k)
    for kept in ((x - y) ** 2, x * y + 1, (x + y) / (x - y)):
        assert conditioning.cancel_sums(kept) == kept


def _substituted(spec: str, monkeypatch) -> flatness.FlatSystem:
    """The flat system as derived without the choice of form: F-bar and G-bar as substituted."""
    with monkeypatch.context() as m:
        m.setattr(conditioning, "better_conditioned", lambda expr, *_: expr)
        return flatness.derive(model.load(spec))


def test_the_flexible_joints_f_bar_does_not_cancel(tmp_path, monkeypatch):
    """Spong's joint, I q1'' = -MgL sin q1 - k (q1 - q2), Jm q2'' = k (q1 - q2) + u, differentiated
    twice with k (q1 - q2) = -(I q1'' + MgL sin q1) (a closed form by hand, independent of the
    derivation): F = MgL q1'^2 sin q1 / I - MgL q1'' cos q1 / I - k q1'' / I - k q1'' / Jm
    - k MgL sin q1 / (I Jm), G = k / (I Jm). The derived F equals it, and computed in float32 it
    is as near its double value as the closed form (within 2x, measured 0.8x: both sum terms
    that do not cancel), where the substituted form, k^2 (q1 - q2(zeta)) / (I Jm) + ..., is more than 10x
    farther (measured 47x: the rounding of q1 times k^2 / (I Jm) = 8.0e6)."""
    path = tmp_path / "flex.toml"
    path.write_text(FLEX_JOINT)
    flat = flatness.derive(model.load(str(path)))
    MgL, I, Jm, k = sp.symbols("MgL I Jm k")
    z0, z1, z2, _ = flat.zeta
    closed = (MgL * z1**2 * sp.sin(z0) / I - MgL * z2 * sp.cos(z0) / I - k * z2 / I - k * z2 / Jm
              - k * MgL * sp.sin(z0) / (I * Jm))
    assert sp.simplify(flat.F[0] - closed) == 0
    assert sp.simplify(flat.G[0] - k / (I * Jm)) == 0
    points = conditioning.canonical_points(flat.model, flat.phi, flat.chains)
    derived, by_hand = (conditioning.float32_error(e, flat.zeta, flat.model, points) for e in (flat.F[0], closed))
    substituted = conditioning.float32_error(_substituted(str(path), monkeypatch).F[0], flat.zeta, flat.model, points)
    assert derived <= 2 * by_hand and substituted > 10 * derived, (derived, by_hand, substituted)


def test_a_form_that_loses_nothing_is_kept(monkeypatch):
    """Nothing cancels in the motor's F-bar (the rewriting leaves it as it is) and the arm's
    rewritten entries compute in float32 no nearer (3.1e-7 of their largest value either way,
    for 14-17% more instructions): both keep their substituted forms, so the built-in models'
    generated C does not move."""
    for name in ("dc_motor_link", "two_link_arm"):
        flat, plain = flatness.derive(model.load(name)), _substituted(name, monkeypatch)
        assert flat.F == plain.F and flat.G == plain.G, name


def test_the_quadrotors_yaw_torque_does_not_move_its_position():
    """A torque about the thrust axis turns the quadrotor about that axis and not the thrust, so
    the snap of its position does not depend on it: G's yaw-torque column is 0 in the three
    position rows. Substituted, the x and y entries were 54-instruction expressions equal to 0
    only by cancellation (rounding noise in float32 where the value is 0); rewritten, they are
    the number 0."""
    flat = flatness.derive(model.load(str(DATA / "quadrotor3d_inverse.toml")))
    assert [u.name for u in flat.model.inputs][-1] == "tau_psi"
    assert [flat.G[row, 3] for row in range(3)] == [0, 0, 0]
