"""Dynamic extension, Phi^-1 where the robot operates, numeric rank decisions and the CPU budget:
models the project has never seen (a unicycle, a PVTOL, a fully coupled 3-DOF arm) and one model
per refusal reason, each checked against a closed form worked out by hand."""

import time
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from dfeif_codegen import budget
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import flatness, inverse, model

DATA = Path(__file__).parent / "data"


def _toml(states, inputs, f, g, outputs, params=""):
    """A small model file: states/inputs as (name, extra TOML) pairs, f and g as dicts."""
    text = '[model]\nname = "toy"\nts = 0.01\n'
    text += "".join(f'[[states]]\nname = "{s}"\n{extra}\n' for s, extra in states)
    text += "".join(f'[[inputs]]\nname = "{u}"\n{extra}\n' for u, extra in inputs)
    text += params + "[dynamics.f]\n" + "".join(f'{k} = "{v}"\n' for k, v in f.items())
    for u, col in g.items():
        text += f"[dynamics.g.{u}]\n" + "".join(f'{k} = "{v}"\n' for k, v in col.items())
    return text + "".join(f'[[outputs]]\nname = "{o}"\nexpr = "{e}"\n' for o, e in outputs)


UNICYCLE = _toml([("px", "min = -3.0\nmax = 3.0"), ("py", "min = -3.0\nmax = 3.0"),
                  ("th", "min = -3.14\nmax = 3.14\nnominal = 0.0")],
                 [("v", "min = 0.05\nmax = 1.5\nnominal = 0.5"), ("w", "")],
                 {"px": "0", "py": "0", "th": "0"}, {"v": {"px": "cos(th)", "py": "sin(th)"}, "w": {"th": "1"}},
                 [("x", "px"), ("y", "py")])

PVTOL = _toml([("x", "min = -3.0\nmax = 3.0"), ("z", "min = -3.0\nmax = 3.0"), ("th", "min = -1.2\nmax = 1.2"),
               ("vx", "min = -3.0\nmax = 3.0"), ("vz", "min = -3.0\nmax = 3.0"), ("om", "min = -3.0\nmax = 3.0")],
              [("T", "min = 2.0\nmax = 12.0"), ("tau", "")],
              {"x": "vx", "z": "vz", "th": "om", "vx": "0", "vz": "-g", "om": "0"},
              {"T": {"vx": "-sin(th)/m", "vz": "cos(th)/m"}, "tau": {"om": "1/J"}},
              [("px", "x"), ("pz", "z")],
              '[[parameters]]\nname = "m"\nvalue = 0.7\n[[parameters]]\nname = "g"\nvalue = 9.81\n'
              '[[parameters]]\nname = "J"\nvalue = 0.005\n')


def test_unicycle_is_extended_by_one_integrator_on_its_speed():
    flat = flatness.derive(model.loads_toml(UNICYCLE))
    assert flat.degrees == [2, 2] and flat.extension.chains == {"v": ("v",), "w": ()}
    assert [s.name for s in flat.model.states] == ["px", "py", "th", "v"]
    assert [u.name for u in flat.model.inputs] == ["v_d1", "w"]
    for th in (0.0, 1e-4, -2.5, 3.1):        # heading 0 and next to it included: atan2, not half-angles
        x = np.array([0.3, -0.2, th, 0.7])
        assert np.allclose(flat.phi_inv_num(flat.phi_num(x)), x, rtol=0, atol=1e-12)
        # closed form: x'' = a cos th - v w sin th, y'' = a sin th + v w cos th, det G = v
        G = flat.G_num(flat.phi_num(x))
        assert np.allclose(G, [[np.cos(th), -0.7 * np.sin(th)], [np.sin(th), 0.7 * np.cos(th)]], atol=1e-12)


def test_pvtol_is_extended_by_two_integrators_on_its_thrust_and_inverts_at_hover():
    flat = flatness.derive(model.loads_toml(PVTOL))
    assert flat.degrees == [4, 4] and flat.extension.chains == {"T": ("T", "T_d1"), "tau": ()}
    m, g, J = 0.7, 9.81, 0.005
    for x in ([0.1, -0.3, 0.0, 0.2, 0.0, 0.0, m * g, 0.0], [1.0, 2.0, -0.8, -1.0, 0.5, 1.5, 9.0, -3.0]):
        x = np.array(x)
        zeta = flat.phi_num(x)
        assert np.allclose(flat.phi_inv_num(zeta), x, rtol=0, atol=1e-9)
        th, T = x[2], x[6]   # closed form: x'''' = ... + [-sin/m, -T cos/(m J)] [T'', tau]
        assert np.allclose(flat.G_num(zeta), [[-np.sin(th) / m, -T * np.cos(th) / (m * J)],
                                              [np.cos(th) / m, -T * np.sin(th) / (m * J)]], atol=1e-9)


def test_float32_check_rejects_the_half_angle_form_and_keeps_atan2():
    flat = flatness.derive(model.loads_toml(UNICYCLE))
    x1, y1 = sp.symbols("x_1 y_1")
    rows = inverse.domain_points(flat.model)
    zeta_rows = np.array([flat.phi_num(r) for r in rows])
    index = {v: i for i, v in enumerate(flat.model.x)}
    th = sp.Symbol("th")
    half = {th: -2 * sp.atan((x1 - sp.sqrt(x1**2 + y1**2)) / y1)}
    good = {th: sp.atan2(y1, x1)}
    ok_half = inverse._float32_trips(half, rows, zeta_rows, flat.zeta, {}, index)
    ok_good = inverse._float32_trips(good, rows, zeta_rows, flat.zeta, {}, index)
    assert ok_good.all() and not ok_half[0] and not ok_half[-inverse.NEAR_NOMINAL:].all()


REFUSALS = {
    # both inputs enter both rows together: delaying channels cannot separate them
    "not cured": (_toml([("x1", ""), ("x2", "")], [("u1", ""), ("u2", "")], {"x1": "0", "x2": "0"},
                        {"u1": {"x1": "1", "x2": "1"}, "u2": {"x1": "1", "x2": "1"}}, [("y1", "x1"), ("y2", "x2")]),
                  ["do not cure", "not flat"]),
    # x3 is driven by itself and seen by neither output: one dimension of zero dynamics
    "internal dynamics": (_toml([("x1", ""), ("x2", ""), ("x3", "")], [("u1", ""), ("u2", "")],
                                {"x1": "0", "x2": "0", "x3": "-x3 + x1"}, {"u1": {"x1": "1"}, "u2": {"x2": "1"}},
                                [("y1", "x1"), ("y2", "x2")]), ["internal (zero) dynamics of dimension 1"]),
    # u enters y' = x u, which vanishes at the declared nominal x = 0 only
    "not defined at a point": (_toml([("x", "min = -1.0\nmax = 1.0\nnominal = 0.0")], [("u", "")], {"x": "0"},
                                     {"u": {"x": "x"}}, [("y", "x")]), ["not defined at the nominal state", "x = 0"]),
}


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_each_refusal_names_its_reason(case):
    text, needles = REFUSALS[case]
    with pytest.raises(ModelError) as err:
        flatness.derive(model.loads_toml(text))
    for needle in needles:
        assert needle in str(err.value)


def _mass_matrix(q, m, l, Jm):
    """Independent expectation: the planar arm's M(q) from the point masses' Jacobians."""
    n, th = len(q), np.cumsum(q)
    M = np.diag(Jm).astype(float)
    for k in range(n):
        Jk = np.zeros((2, n))
        for i in range(k + 1):
            Jk[:, i] = sum(l[a] * np.array([-np.sin(th[a]), np.cos(th[a])]) for a in range(i, k + 1))
        M += m[k] * Jk.T @ Jk
    return M


def test_fully_coupled_3dof_arm_with_symbolic_parameters_derives_within_60_cpu_seconds():
    mdl = model.load(str(DATA / "planar_arm3.toml"))
    start = time.process_time()
    flat = budget.bounded(flatness.derive, (mdl,), 60.0, 2.0, "deriving planar_arm3")
    assert time.process_time() - start < 60
    assert flat.degrees == [2, 2, 2]
    p = {q.name: q.value for q in mdl.parameters}
    q = np.array([0.4, -1.1, 0.7])
    zeta = flat.phi_num(np.concatenate([q, [0.3, -0.2, 0.5]]))
    M = _mass_matrix(q, [p["m1"], p["m2"], p["m3"]], [p["l1"], p["l2"], p["l3"]], [p["Jm1"], p["Jm2"], p["Jm3"]])
    assert np.allclose(flat.G_num(zeta), np.linalg.inv(M), rtol=1e-9, atol=1e-9)   # G = M^-1


def test_budget_counts_cpu_seconds_not_wall_clock():
    assert budget.bounded(_sleep, (1.5,), 1.0, 2.0, "sleeping") == "slept"   # 1.5 s of wall, ~0 CPU-s
    with pytest.raises(budget.BudgetError, match="stopped after 0.5 CPU-s while spinning"):
        budget.bounded(_spin, (), 0.5, 2.0, "busy")


def _sleep(seconds, progress=None):
    time.sleep(seconds)
    return "slept"


def _spin(progress=None):
    if progress:
        progress("spinning")
    while True:
        pass


def test_inspect_warns_where_g_bar_crosses_zero_inside_the_domain(capsys):
    """g-bar = cos(x1) on x1 in [-2, 2] changes sign at +-pi/2; the motor's g-bar = k_e/(J L) is a
    constant, so it gets no warning."""
    from dfeif_codegen import cli

    text = _toml([("x1", "min = -2.0\nmax = 2.0\nnominal = 0.0"), ("x2", "min = -1.0\nmax = 1.0")], [("u", "")],
                 {"x1": "x2", "x2": "0"}, {"u": {"x2": "cos(x1)"}}, [("y", "x1")])
    from dfeif_codegen.symbolic import inspect_model
    info = inspect_model.inspect(model.loads_toml(text))
    assert len(info["warnings"]) == 1 and "g_bar changes sign" in info["warnings"][0]
    x1 = float(info["warnings"][0].split("x1 = ")[1].split(",")[0])
    assert abs(abs(x1) - np.pi / 2) < 0.1        # the smallest |g_bar| sampled lies next to the zero
    assert cli.main(["inspect", "dc_motor_link"]) == 0
    assert "warning" not in capsys.readouterr().out


def test_fully_coupled_3dof_arm_with_motors_derives_within_60_cpu_seconds():
    """Relative degree 3: Phi^-1 solves the currents from the accelerations (a linear system, by
    LU) and F-bar substitutes them (xreplace); G-bar = (k_e / L) M(q)^-1."""
    mdl = model.load(str(DATA / "planar_arm3_motors.toml"))
    flat = budget.bounded(flatness.derive, (mdl,), 60.0, 2.0, "deriving planar_arm3m")
    assert flat.degrees == [3, 3, 3]
    p = {q.name: q.value for q in mdl.parameters}
    q, w, current = np.array([0.4, -1.1, 0.7]), np.array([0.3, -0.2, 0.5]), np.array([1.0, -0.5, 0.2])
    x = np.concatenate([q, w, current])
    zeta = flat.phi_num(x)
    np.testing.assert_allclose(flat.phi_inv_num(zeta), x, rtol=1e-9, atol=1e-9)
    M = _mass_matrix(q, [p["m1"], p["m2"], p["m3"]], [p["l1"], p["l2"], p["l3"]], [p["Jm1"], p["Jm2"], p["Jm3"]])
    np.testing.assert_allclose(flat.G_num(zeta), p["k_e"] / p["L"] * np.linalg.inv(M), rtol=1e-9, atol=1e-9)


def test_an_undeclared_branch_names_each_variable_where_the_user_declared_it(tmp_path, capsys):
    """The planar quadrotor without domains on its roll angle and its thrust: Phi^-1 has two
    branches (thrust up or down). T is an input the extension made a state: the message sends
    the user to its [[inputs]] entry, not to a `states[7]` the file does not have."""
    from importlib import resources

    from dfeif_codegen import cli
    text = (resources.files("dfeif_codegen.models") / "pvtol.toml").read_text(encoding="utf-8")
    text = text.replace("min = -1.2\nmax = 1.2\nnominal = 0.0\n", "").replace("min = 1.5\nmax = 15.0\n", "")
    lines = text.splitlines()
    th_line = lines.index('name = "th"')         # 1-based: the entry's [[states]] header, just above
    t_line = lines.index('name = "T"')
    path = tmp_path / "pvtol.toml"
    path.write_text(text)
    assert cli.main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "several branches for T, th" in err[0]
    assert err[0].startswith(f"codegen inspect: error: {path}:{th_line}: states[3]:")
    assert f"(T: {path}:{t_line}: inputs[1], an input the extension made a state)" in err[0]


def test_an_output_of_its_own_keeps_its_input_undelayed():
    """The minimal extension: a unicycle carrying a turret (an output of its own, al' = wt).
    Only v enters the dependent rows (x, y), so only v gets an integrator: relative degrees
    (2, 2, 1) on 5 states. Delaying every input that enters the decoupling matrix (the rule
    before) also put one on the turret: (2, 2, 2) on 6 states, an estimated turret acceleration
    that no camera needs."""
    from dfeif_codegen.symbolic import extension
    extended, ext, io = extension.extend(model.load(str(DATA / "turret_robot.toml")))
    assert io.degrees == [2, 2, 1] and extended.n == 5
    assert ext.chains == {"v": ("v",), "w": (), "wt": ()}


@pytest.mark.parametrize("body_rates", [True, False])
def test_a_3d_quadrotor_gets_two_integrators_on_its_thrust(body_rates):
    """Position rows (x, y, z) depend on T alone at relative degree 2; the yaw row has its own
    torques (with body rates: two of them, through the Euler kinematics, which the rule before
    refused as "not flat"; with Euler-angle rates one, which it delayed too: 16 states). The
    textbook extension: T twice, relative degrees (4, 4, 4, 2), 14 states, the decoupling matrix
    regular at the hover (its determinant there, by hand: T^2 / (m^3 Ix Iy Iz) up to sign)."""
    from dfeif_codegen.symbolic import extension
    text = (DATA / "quadrotor3d.toml").read_text()
    if not body_rates:   # Euler-angle rates: the angles integrate their rates, driven by the torques
        text = text.replace('phi = "p + sin(phi)*tan(theta)*q + cos(phi)*tan(theta)*r"', 'phi = "p"')
        text = text.replace('theta = "cos(phi)*q - sin(phi)*r"', 'theta = "q"')
        text = text.replace('psi = "(sin(phi)*q + cos(phi)*r)/cos(theta)"', 'psi = "r"')
        text = text.replace('p = "(Iy - Iz)*q*r/Ix"', 'p = "0"').replace('q = "(Iz - Ix)*p*r/Iy"', 'q = "0"')
        text = text.replace('r = "(Ix - Iy)*p*q/Iz"', 'r = "0"')
    extended, ext, io = extension.extend(model.loads_toml(text, "quadrotor3d.toml"))
    assert io.degrees == [4, 4, 4, 2] and extended.n == 14
    assert ext.chains == {"T": ("T", "T_d1"), "tau_phi": (), "tau_theta": (), "tau_psi": ()}
    m, Ix, Iy, Iz, T = 0.5, 0.0049, 0.0049, 0.0088, 4.905
    assert abs(np.linalg.det(io.samples[0])) == pytest.approx(T ** 2 / (m ** 3 * Ix * Iy * Iz), rel=1e-9)
