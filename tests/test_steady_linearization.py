"""``ConstrainedSystem.linearize(..., independent=...)``: linearization about steady
motions in independent coordinates and speeds. The four-bar about its hanging
equilibrium against the closed-form loop closure (reduced mass and stiffness of the one
coordinate), the leaning rolling disk about straight upright rolling against SymPy's
``KanesMethod.linearize``, and the errors: a point that is not steady, a singular
dependent block, the wrong number of indices, a point off the constraints."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.bodies import Param, Scene, SpatialBody

# --------------------------------------------------------------------------- four-bar


def _closed_loop(theta1, p, sign):
    """`q(θ1)` of the four-bar in closed form: the coupler–rocker joint `B` is where the
    circles of radius `l2` about the crank tip and `l3` about the rocker pivot meet."""
    a = p["l1"] * jnp.stack([jnp.cos(theta1), jnp.sin(theta1)])
    pivot = jnp.stack([p["d"], 0.0 * p["d"]])
    gap = pivot - a
    dist = jnp.linalg.norm(gap)
    along = (p["l2"] ** 2 - p["l3"] ** 2 + dist**2) / (2 * dist)
    height = jnp.sqrt(p["l2"] ** 2 - along**2)
    perp = jnp.stack([-gap[1], gap[0]]) / dist
    b = a + along * gap / dist + sign * height * perp
    theta2 = jnp.arctan2(b[1] - a[1], b[0] - a[0])
    theta3 = jnp.arctan2(b[1] - pivot[1], b[0] - pivot[0])
    return jnp.stack([theta1, theta2, theta3])


@pytest.fixture(scope="module")
def four_bar_equilibrium():
    """The hanging equilibrium of the default crank–rocker: Newton on `dV(q(θ1))/dθ1`,
    with the reduced mass `m = Pᵀ M P`, stiffness `k = d²V(q(θ1))/dθ1²` and
    `P = dq/dθ1` of the closed form."""
    system, p = lx.models.four_bar()
    sign = -1.0

    def reduced_v(theta1):
        return system.potential_energy(_closed_loop(theta1, p, sign), p)

    dv, d2v = jax.jit(jax.grad(reduced_v)), jax.jit(jax.grad(jax.grad(reduced_v)))
    theta1 = jnp.asarray(-1.4)
    for _ in range(30):
        theta1 = theta1 - dv(theta1) / d2v(theta1)
    q = _closed_loop(theta1, p, sign)
    tangent = jax.jacfwd(lambda s: _closed_loop(s, p, sign))(theta1)
    mass = tangent @ system.mass_matrix(q, p) @ tangent
    return system, p, q, tangent, float(mass), float(d2v(theta1))


def test_four_bar_about_equilibrium_in_one_coordinate(four_bar_equilibrium):
    """`A = [[0, 1], [−k/m, 0]]`, `B = [[0], [Pᵀ/m]]` in the crank angle."""
    system, p, q, tangent, mass, stiffness = four_bar_equilibrium
    assert np.max(np.abs(system.violation(q, p))) < 1e-14 and stiffness > 0
    a_mat, b_mat = system.linearize(q, jnp.zeros(3), p, independent=[0])
    np.testing.assert_allclose(a_mat, [[0.0, 1.0], [-stiffness / mass, 0.0]], atol=1e-12)
    np.testing.assert_allclose(b_mat[0], 0.0, atol=1e-15)
    np.testing.assert_allclose(b_mat[1], np.asarray(tangent) / mass, rtol=1e-11, atol=1e-14)


def test_four_bar_other_independent_coordinate(four_bar_equilibrium):
    """With the rocker angle independent, the frequency is the same, `√(k/m)`."""
    system, p, q, _, mass, stiffness = four_bar_equilibrium
    a_mat, _ = system.linearize(q, jnp.zeros(3), p, independent=([2], [2]))
    eigs = np.linalg.eigvals(np.asarray(a_mat))
    np.testing.assert_allclose(
        np.sort(eigs.imag),
        [-np.sqrt(stiffness / mass)] * 1 + [np.sqrt(stiffness / mass)],
        rtol=1e-11,
    )
    np.testing.assert_allclose(eigs.real, 0.0, atol=1e-9)


def test_four_bar_not_at_rest_is_refused(four_bar_equilibrium):
    """Away from the equilibrium the crank accelerates: the error names its coordinate."""
    system, p, q, _, _, _ = four_bar_equilibrium
    q_off, _ = system.project(q + jnp.array([0.2, 0.0, 0.0]), jnp.zeros(3), p)
    with pytest.raises(lx.LagraxError, match=r"not a steady motion.*q\[0\]"):
        system.linearize(q_off, jnp.zeros(3), p, independent=[0])


def test_singular_dependent_block_names_the_coordinates():
    """The Cartesian pendulum hanging at `(0, −l)`: `∂φ/∂x = 0`, so `x` cannot be the
    dependent coordinate; `y` can."""
    system, p = lx.models.cartesian_pendulum()
    q = jnp.array([0.0, -float(p["l"])])
    with pytest.raises(lx.ConstraintError, match=r"dependent coordinates q\[0\]"):
        system.linearize(q, jnp.zeros(2), p, independent=[1])
    a_mat, _ = system.linearize(q, jnp.zeros(2), p, independent=[0])
    np.testing.assert_allclose(a_mat, [[0.0, 1.0], [-float(p["g"] / p["l"]), 0.0]], rtol=1e-13)


def test_bad_independent_indices(four_bar_equilibrium):
    system, p, q, _, _, _ = four_bar_equilibrium
    with pytest.raises(lx.ConfigurationError, match="needs 1 independent coordinates"):
        system.linearize(q, jnp.zeros(3), p, independent=[0, 1])
    with pytest.raises(lx.ConfigurationError, match="distinct indices"):
        system.linearize(q, jnp.zeros(3), p, independent=[5])
    with pytest.raises(lx.ConfigurationError, match="tol must be"):
        system.linearize(q, jnp.zeros(3), p, independent=[0], tol=0.0)
    with pytest.raises(lx.ConstraintError, match="not on its constraints"):
        system.linearize(q + 0.1, jnp.zeros(3), p, independent=[0])


# --------------------------------------------------------------------------- rolling disk
# A thin uniform disk (mass m, radius R) rolling without slip on the plane z = 0:
# q = (x, y, ψ, θ, φ) the contact point, yaw, lean and spin; the disk's orientation
# Rz(ψ) Rx(θ) Ry(φ), its centre R above the contact along the leaned frame's z axis.


def _rot(axis, angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = 1.0 + 0.0 * angle, 0.0 * angle
    rows = {
        "x": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return jnp.stack([jnp.stack(r) for r in rows])


def _lean_frame(q):
    return _rot("z", q[2]) @ _rot("x", q[3])


def _disk_pose(q, p):
    frame = _lean_frame(q)
    centre = jnp.stack([q[0], q[1], 0.0 * q[0]]) + p["R"] * frame[:, 2]
    return centre, frame @ _rot("y", q[4])


def _no_slip(q, p):
    """Rows of the contact point's material velocity `v_C + ω × (r_P − r_C)`, horizontal
    components: column j is `∂r_C/∂q_j + (∂R/∂q_j) Rᵀ (r_P − r_C)`."""
    centre, rot = _disk_pose(q, p)
    d_centre, d_rot = jax.jacfwd(lambda a: _disk_pose(a, p))(q)
    arm = -p["R"] * _lean_frame(q)[:, 2]
    cols = d_centre + jnp.einsum("abj,cb,c->aj", d_rot, rot, arm)
    return cols[:2]


@pytest.fixture(scope="module")
def rolling_disk():
    inertia = lambda p: p["m"] * p["R"] ** 2 * jnp.diag(jnp.array([0.25, 0.5, 0.25]))  # noqa: E731
    body = SpatialBody(Param("m"), inertia, _disk_pose, None)
    free = Scene([body], gravity=Param("g"), n_dof=5).system()
    system = lx.ConstrainedSystem(free, velocity_constraints=_no_slip, name="rolling disk")
    return system, {"m": 2.0, "R": 0.3, "g": 9.81}


def _sympy_disk(params, spin):
    """`A` of the same disk by SymPy's `KanesMethod.linearize` (speeds `u = q̇`, the
    contact speeds `ẋ, ẏ` dependent), state `(x, y, ψ, θ, φ, ψ̇, θ̇, φ̇)`."""
    sm = pytest.importorskip("sympy")
    me = pytest.importorskip("sympy.physics.mechanics")
    q = me.dynamicsymbols("x y psi theta phi")
    u = me.dynamicsymbols("u1:6")
    m, r, g = sm.symbols("m R g")
    frame_n = me.ReferenceFrame("N")
    yaw = frame_n.orientnew("Y", "Axis", [q[2], frame_n.z])
    lean = yaw.orientnew("L", "Axis", [q[3], yaw.x])
    disk = lean.orientnew("D", "Axis", [q[4], lean.y])
    to_u = {a.diff(): b for a, b in zip(q, u, strict=True)}
    disk.set_ang_vel(frame_n, disk.ang_vel_in(frame_n).subs(to_u))
    origin = me.Point("O")
    origin.set_vel(frame_n, 0)
    centre = origin.locatenew("C", q[0] * frame_n.x + q[1] * frame_n.y + r * lean.z)
    centre.set_vel(frame_n, centre.pos_from(origin).dt(frame_n).subs(to_u))
    contact = centre.vel(frame_n) + disk.ang_vel_in(frame_n).cross(-r * lean.z)
    inertia = me.inertia(disk, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4)
    kane = me.KanesMethod(
        frame_n,
        q_ind=q,
        u_ind=u[2:],
        u_dependent=u[:2],
        kd_eqs=[a.diff() - b for a, b in zip(q, u, strict=True)],
        velocity_constraints=[contact.dot(frame_n.x), contact.dot(frame_n.y)],
    )
    kane.kanes_equations(
        [me.RigidBody("disk", centre, disk, m, (inertia, centre))], [(centre, -m * g * frame_n.z)]
    )
    values = {m: params["m"], r: params["R"], g: params["g"]}
    speeds = [params["R"] * spin, 0, 0, 0, spin]
    op = {**{a: 0 for a in q}, **dict(zip(u, speeds, strict=True))}
    rates = {a.diff(): s for a, s in zip(q, speeds, strict=True)}
    accelerations = {b.diff(): 0 for b in u}
    a_mat, _, _ = kane.linearize(op_point=[op, rates, accelerations, values], A_and_B=True)
    return np.array(sm.N(a_mat.subs(values)), dtype=float)


def test_rolling_disk_against_sympy(rolling_disk):
    system, p = rolling_disk
    spin = 7.0
    q = jnp.zeros(5)
    qd = jnp.array([p["R"] * spin, 0.0, 0.0, 0.0, spin])
    a_mat, b_mat = system.linearize(q, qd, p, independent=(range(5), [2, 3, 4]))
    assert a_mat.shape == (8, 8) and b_mat.shape == (8, 5)
    np.testing.assert_allclose(a_mat, _sympy_disk(p, spin), rtol=1e-12, atol=1e-12)


def test_rolling_disk_leaning_straight_is_not_steady(rolling_disk):
    """A disk leaning 0.1 rad and rolling straight falls further: the lean's reduced
    acceleration is named."""
    system, p = rolling_disk
    q = jnp.array([0.0, 0.0, 0.0, 0.1, 0.0])
    qd = jnp.array([p["R"] * 5.0, 0.0, 0.0, 0.0, 5.0])
    with pytest.raises(lx.LagraxError, match=r"q\[3\] = "):
        system.linearize(q, qd, p, independent=(range(5), [2, 3, 4]))


def test_rolling_disk_under_jit_and_vmap(rolling_disk):
    """Traced: the same matrices, one compiled call over several spins."""
    system, p = rolling_disk
    spins = jnp.array([2.0, 7.0])

    def lin(spin):
        qd = jnp.stack([p["R"] * spin, 0.0 * spin, 0.0 * spin, 0.0 * spin, spin])
        return system.linearize(jnp.zeros(5), qd, p, independent=(range(5), [2, 3, 4]))[0]

    batched = jax.jit(jax.vmap(lin))(spins)
    for k, spin in enumerate(np.asarray(spins)):
        np.testing.assert_allclose(batched[k], _sympy_disk(p, float(spin)), atol=1e-12)
