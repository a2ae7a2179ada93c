"""Entries of Phi^-1 given in a model's [inverse] table (symbolic/given_inverse.py): taken as
solved, checked by round trips like a branch the solver found, refused at their line when they do
not invert Phi; a 3-D quadrotor, whose attitude sympy does not solve for, derives with them."""

import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from dfeif_codegen import cli
from dfeif_codegen.codegen import provenance
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import flatness, model
from test_domains import SQRT_MOTOR, physical_current

DATA = Path(__file__).parent / "data"
ROOT = 'I = "sqrt((J*theta_2 + c*theta_1 + ks*theta_0)/k)"'


def _with_inverse(entries: str) -> tuple[model.Model, int]:
    """sqrt_motor.toml with an [inverse] table appended, and the line of its first entry."""
    text = SQRT_MOTOR.read_text(encoding="utf-8").rstrip("\n") + "\n\n[inverse]\n" + entries + "\n"
    line = text.splitlines().index(entries.splitlines()[0]) + 1
    return model.loads_toml(text, "sqrt_inv.toml"), line


def _phi_inv_at(flat, zeta_rows: np.ndarray) -> np.ndarray:
    f = sp.lambdify(flat.zeta, list(flat.phi_inv.subs(flat.model.param_values)), "numpy")
    return np.array([np.asarray(f(*z), dtype=float) for z in zeta_rows])


def test_a_given_root_gives_the_physical_branch():
    given = flatness.derive(_with_inverse(ROOT)[0])
    solved = flatness.derive(model.load(str(SQRT_MOTOR)))
    rng = np.random.default_rng(3)
    # zeta = (theta, omega, theta'') at currents inside the domain [0.05, 5] A
    zeta = np.column_stack([rng.uniform(-1, 1, 20), rng.uniform(-2, 2, 20), rng.uniform(0, 50, 20)])
    zeta[:, 2] = (0.5 * rng.uniform(0.05, 5, 20) ** 2 - 0.05 * zeta[:, 1] - zeta[:, 0]) / 0.02
    current = [physical_current(z) for z in zeta]
    assert given.phi_inv[2] == sp.sympify("sqrt((J*theta_2 + c*theta_1 + ks*theta_0)/k)")
    np.testing.assert_allclose(_phi_inv_at(given, zeta)[:, 2], current, rtol=1e-12)
    np.testing.assert_allclose(_phi_inv_at(given, zeta), _phi_inv_at(solved, zeta), rtol=1e-12)


def test_the_negative_root_is_refused_at_its_line():
    m, line = _with_inverse(ROOT.replace('"sqrt', '"-sqrt'))
    with pytest.raises(ModelError, match=rf"^sqrt_inv\.toml:{line}: inverse\.I: does not invert Phi at "
                                         r"theta = .*, I = 1: it gives -1$"):
        flatness.derive(m)


@pytest.mark.parametrize("entry, problem", [
    ('Q = "theta_0"', r"'Q' is not a state of the model"),
    ('V_d1 = "theta_0"', r"'V_d1' is not a state of the model as derived \(states: theta, omega, I\)"),
    ('I = "sqrt(omega)"', r"column 6: undeclared name 'omega'"),
    ('I = "sqrt(theta_2"', r"column \d+: "),
    ("I = 2.0", r"must be a string"),
])
def test_a_bad_entry_names_its_line_and_key(entry, problem):
    key = entry.split()[0]
    with pytest.raises(ModelError, match=rf"^sqrt_inv\.toml:\d+: inverse\.{key}: {problem}") as err:
        flatness.derive(_with_inverse(entry)[0])
    line = int(re.match(r"sqrt_inv\.toml:(\d+)", str(err.value)).group(1))
    text = SQRT_MOTOR.read_text(encoding="utf-8").rstrip("\n") + "\n\n[inverse]\n" + entry
    assert text.splitlines()[line - 1] == entry and "\n" not in str(err.value)


def test_the_inverse_table_changes_the_model_hash():
    plain = provenance.model_hash(model.load(str(SQRT_MOTOR)))
    given = provenance.model_hash(_with_inverse(ROOT)[0])
    other = provenance.model_hash(_with_inverse(ROOT.replace("ks*", "1.0*ks*"))[0])
    assert len({plain, given, other}) == 3


def test_quadrotor_with_given_attitude_inverts_phi():
    """Phi^-1(Phi(x)) = x at 200 random states of the declared domain (T_d1, undeclared, in
    [-20, 20] N/s). Tolerance 1e-9 (1 + |x|): the composition is a few dozen double operations on
    values of order 10 (about 1e-13 of rounding); a wrong branch or sign is off by O(|x|)."""
    flat = flatness.derive(model.load(str(DATA / "quadrotor3d_inverse.toml")))
    states = flat.model.states
    assert [s.name for s in states][-2:] == ["T", "T_d1"] and len(flat.zeta) == 14
    rng = np.random.default_rng(11)
    lo = np.array([-20.0 if s.min is None else s.min for s in states])
    hi = np.array([20.0 if s.max is None else s.max for s in states])
    x = rng.uniform(lo, hi, (200, len(states)))
    phi = sp.lambdify(list(flat.model.x), list(flat.phi.subs(flat.model.param_values)), "numpy")
    zeta = np.array([np.asarray(phi(*row), dtype=float) for row in x])
    back = _phi_inv_at(flat, zeta)
    assert np.all(np.abs(back - x) <= 1e-9 * (1 + np.abs(x))), np.max(np.abs(back - x))


def test_quadrotor_with_given_attitude_verifies_on_the_host(capsys):
    """The generated C against the Python reference on a figure eight with late frames (about
    10 s): the given entries reach the C through Phi^-1 like solved ones."""
    assert cli.main(["verify", str(DATA / "quadrotor3d_inverse.toml"),
                     "--scenario", str(DATA / "quadrotor3d_scenario.toml")]) == 0
    assert capsys.readouterr().out.rstrip().endswith("PASS")
