"""State domains (issue 11): the branch of Phi^-1 on the declared domain, the physical sign of
G-bar and of the C command, ERR_SINGULAR near a singularity, input saturation in the C and the
reference, and a reference that asks for a state outside the domain.

The model (tests/data/sqrt_motor.toml): torque k I^2, so theta'' = (k I^2 - c omega - ks theta)/J
gives I = +-sqrt((J theta'' + c theta' + ks theta)/k); the current's domain is [0.05, 5] A."""

import ctypes
import warnings
from pathlib import Path

import numpy as np
import pytest

from dfeif_codegen.check import harness
from dfeif_codegen.codegen import build
from dfeif_codegen.errors import ModelError
from dfeif_codegen.experiment import closed_loop
from dfeif_codegen.reference.control import FlatController, SingularControl
from dfeif_codegen.symbolic import flatness, model
from test_c_compile import Lib

SQRT_MOTOR = Path(__file__).parent / "data" / "sqrt_motor.toml"
K, KS, C, J, R, L = 0.5, 1.0, 0.05, 0.02, 2.0, 0.005  # the file's parameter values


def physical_current(zeta) -> float:
    """Closed form of the physical branch: I = +sqrt((J theta'' + c theta' + ks theta)/k)."""
    return float(np.sqrt((J * zeta[2] + C * zeta[1] + KS * zeta[0]) / K))


@pytest.fixture(scope="module")
def flat():
    return flatness.derive(model.load(str(SQRT_MOTOR)))


@pytest.fixture(scope="module")
def lib(tmp_path_factory, host_cc):
    """The generated C of the model, built through the public API, as a shared library."""
    root = tmp_path_factory.mktemp("sqrt")
    module = build.build(str(SQRT_MOTOR), root / "gen")
    sources = [p for p in sorted(module.path.glob("*.c")) if p.name != "example_main.c"]
    so = harness.compile_shared(sources, root / "libsqrt.so", [module.path])
    return harness.load(so)


def c_control(lib, zeta, flags, gains, params=None):
    """(return code, u, v, saturation count) of sqrt_motor_control; u and v start at 42."""
    d = ctypes.POINTER(ctypes.c_double)
    arr = [np.ascontiguousarray(a, dtype=float) for a in (zeta, flags, gains)]
    p = np.array([K, KS, C, J, R, L]) if params is None else np.asarray(params, float)
    u, v, sat = np.full(1, 42.0), np.full(1, 42.0), np.zeros(1, dtype=np.uint32)
    rc = lib.sqrt_motor_control(*(a.ctypes.data_as(d) for a in (*arr, p, u, v)),
                                sat.ctypes.data_as(ctypes.POINTER(ctypes.c_uint32)))
    return rc, u[0], v[0], int(sat[0])


def test_branch_is_the_physical_root_on_the_domain(flat):
    # round trip at states drawn from the declared domain, against the closed form
    rng = np.random.default_rng(3)
    for _ in range(200):
        x = np.array([rng.uniform(-1, 1), rng.uniform(-2, 2), rng.uniform(0.05, 5.0)])
        zeta = flat.phi_num(x)
        back = flat.phi_inv_num(zeta)
        # a handful of flops on O(1) numbers: 1e-12 relative is thousands of ulps of margin, and
        # the wrong branch would be off by 2 I >= 0.1
        assert back[2] == pytest.approx(physical_current(zeta), rel=1e-12)
        assert back == pytest.approx(x, rel=1e-12, abs=1e-12)


def test_g_bar_has_the_physical_sign(flat):
    # G-bar = d theta'''/dV = 2 k I / (J L) > 0 for I > 0: more voltage, more torque
    x_nom = flatness.nominal_state(flat.model)
    assert list(x_nom) == [0.5, 0.0, 1.0]
    G = flat.G_num(flat.phi_num(x_nom))[0, 0]
    assert G > 0 and G == pytest.approx(2 * K * 1.0 / (J * L), rel=1e-12)
    assert flat.nominal_det() == pytest.approx(2 * K / (J * L), rel=1e-12)


def test_c_commands_the_physical_polarity_at_the_nominal_point(flat, lib):
    # at the equilibrium (theta 0.5 rad, omega 0, I 1 A) with the reference sitting on it, the
    # control must hold the current: V = R I = +2 V (the negative root would command -2 V)
    zeta = flat.phi_num(flatness.nominal_state(flat.model))
    flags = np.array([zeta[0], 0.0, 0.0, 0.0])
    gains = FlatController(flat, poles=5.0).gains
    rc, u, v, sat = c_control(lib, zeta, flags, gains)
    assert rc == 0 and sat == 0
    # u = -F/G with F = -R I G: ~20 flops on numbers of size 1e4, so 1e-12 relative holds anywhere
    assert u == pytest.approx(R * 1.0, rel=1e-12)
    u_ref, _ = FlatController(flat, poles=5.0)(zeta, flags)
    assert u_ref[0] == pytest.approx(R * 1.0, rel=1e-12)


def test_input_limits_saturate_in_c_and_reference(flat, lib):
    zeta = flat.phi_num(flatness.nominal_state(flat.model))
    flags = np.array([zeta[0], 0.0, 0.0, 1e6])    # asks for theta''' = 1e6: V = (1e6 - F)/G = 102 V
    ctl = FlatController(flat, poles=5.0)
    rc, u, v, sat = c_control(lib, zeta, flags, ctl.gains)
    u_ref, v_ref = ctl(zeta, flags)
    assert rc == 0 and sat == 1 and ctl.saturations == 1
    assert u == 24.0 and u_ref[0] == 24.0          # the declared max, exactly (a clamp, no arithmetic)
    # the v broadcast to the filters is what the clamped V produces: F + G * 24 = (24 - R I) G
    G = flat.G_num(zeta)[0, 0]
    assert v == pytest.approx((24.0 - R) * G, rel=1e-12) and v_ref[0] == pytest.approx(v, rel=1e-12)


def test_near_singular_control_refuses_in_c_and_reference(flat, lib):
    # I = 1e-7 A: |G| = 2 k I/(J L) = 1e-3, 1e-7 of its nominal 1e4, below the default 1e-6
    x = np.array([0.0, 0.0, 1e-7])
    zeta = flat.phi_num(x)
    flags = np.array([0.0, 0.0, 0.0, 0.0])
    ctl = FlatController(flat, poles=5.0)
    rc, u, v, _ = c_control(lib, zeta, flags, ctl.gains)
    assert rc == -4 and u == 42.0 and v == 42.0     # ERR_SINGULAR, outputs untouched
    with pytest.raises(SingularControl, match="below 1e-06 of its nominal"):
        ctl(zeta, flags)
    # ten times more current is 1e-6 of nominal: accepted again
    assert c_control(lib, flat.phi_num(np.array([0.0, 0.0, 1.01e-6])), flags, ctl.gains)[0] == 0


def test_control_outside_the_domain_says_so_in_c_and_reference(flat, lib):
    """A finite estimate whose theta, theta', theta'' ask for I^2 < 0 (k I^2 = J theta'' + c theta'
    + ks theta: 0.5 I^2 = -3.3e-3 at the point `codegen scenario --param-error 0.1` met on this
    model): F and G are NaN there. The reference refuses with what happened (the estimate left the
    model's domain, not "diverged"), without numpy's warning on det(NaN); the C refuses too
    (ERR_SINGULAR, outputs untouched)."""
    zeta = np.array([0.0012, -0.1348, 0.1138])
    assert 0.02 * zeta[2] + 0.05 * zeta[1] + 1.0 * zeta[0] < 0
    flags = np.zeros(4)
    ctl = FlatController(flat, poles=5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SingularControl, match="left the model's domain"):
            ctl(zeta, flags)
    rc, u, v, _ = c_control(lib, zeta, flags, ctl.gains)
    assert rc == -4 and u == 42.0 and v == 42.0


@pytest.mark.parametrize("kind", ["node", "master"])
def test_init_refuses_a_prior_outside_the_domain(flat, lib, kind):
    # the held predictor evaluates G-bar = 2 k I/(J L) at the estimate whatever the input, so from
    # a prior with no real current every predict is NaN: init refuses it (ERR_ARG, the struct's
    # bytes as they were) and takes the nominal state and one inside, near the boundary
    c = Lib(lib, "sqrt_motor")
    P0, R, q = np.diag([1e-4, 1e-2, 1.0]), np.array([1e-6]), np.array([1.0])
    init = (lambda s, x: c("node_init", s, x, P0, R, q)) if kind == "node" else \
        (lambda s, x: c("master_init", s, x, P0, q))
    nominal = flat.phi_num(flatness.nominal_state(flat.model))
    for x0, inside in (([-0.5, 0.0, 0.0], False), ([0.5, 0.0, -30.0], False), ([0.5, 0.0, -20.0], True),
                       (nominal, True)):
        x0 = np.array(x0, dtype=float)
        assert ((J * x0[2] + C * x0[1] + KS * x0[0]) / K > 0) == inside      # I^2, the closed form
        s = c.new(kind)
        pattern = bytes((7 * i + 3) % 256 for i in range(len(s.raw)))
        ctypes.memmove(s, pattern, len(pattern))
        if inside:
            assert init(s, x0) == 0 and s.raw != pattern
        else:
            assert init(s, x0) == -1 and s.raw == pattern       # ERR_ARG, the struct untouched


def test_undeclared_domain_with_two_branches_is_refused(tmp_path):
    text = SQRT_MOTOR.read_text().replace("min = 0.05\nmax = 5.0\n", "")
    path = tmp_path / "free.toml"
    path.write_text(text)
    with pytest.raises(ModelError) as err:
        flatness.derive(model.load(str(path)))
    msg = str(err.value)
    assert "states[3]" in msg and "for I" in msg and msg.count("sqrt") == 2 and "-sqrt" in msg
    assert "\n" not in msg


def test_domain_with_no_single_branch_is_refused(tmp_path):
    path = tmp_path / "both.toml"
    path.write_text(SQRT_MOTOR.read_text().replace("min = 0.05", "min = -1.0").replace("nominal = 1.0", "nominal = 0.5"))
    with pytest.raises(ModelError, match="no branch of Phi\\^-1 for I .* valid on all of its declared domain"):
        flatness.derive(model.load(str(path)))


def test_reference_outside_the_domain_names_expression_and_time(flat):
    # theta_d = -0.5 + 0.1 t: J theta'' + c theta' + ks theta < 0 until t = 4.95 s: no real current
    t = np.arange(10) * 0.01
    rows = [[-0.5 + 0.1 * tk, 0.1, 0.0, 0.0] for tk in t]
    with pytest.raises(closed_loop.UndefinedReference, match=r"t = 0\.000 s .* I = sqrt"):
        closed_loop.check_reference(flat, rows, t)
    closed_loop.check_reference(flat, [[0.5, 0.0, 0.0, 0.0]], t[:1])  # the nominal point is fine
