r"""The Whipple bicycle of the benchmark of Meijaard, Papadopoulos, Ruina & Schwab (2007),
"Linearized dynamics equations for the balance and steer of a bicycle: a benchmark and
review", Proc. R. Soc. A 463:1955–1982: four rigid bodies and two knife-edge wheels
rolling without slip, built from `SpatialBody` and `ConstrainedSystem`; its linearized
matrices and eigenvalues read off the general steady-motion linearization."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from .._core.custom_types import Params
from .._core.errors import ArgumentTypeError
from .._multibody.energies.bodies import SpatialBody
from .._multibody.energies.scene import Scene
from .._systems.constrained import ConstrainedSystem

# Table 1 of the paper (SI units), in its names.
BENCHMARK = dict(
    w=1.02, c=0.08, lam=jnp.pi / 10, g=9.81,
    rR=0.3, mR=2.0, IRxx=0.0603, IRyy=0.12,
    xB=0.3, zB=-0.9, mB=85.0, IBxx=9.2, IByy=11.0, IBzz=2.8, IBxz=2.4,
    xH=0.9, zH=-0.7, mH=4.0, IHxx=0.05892, IHyy=0.06, IHzz=0.00708, IHxz=-0.00756,
    rF=0.35, mF=3.0, IFxx=0.1405, IFyy=0.28,
)  # fmt: skip

COORDINATES = ("x", "y", "yaw", "lean", "pitch", "steer", "rear wheel", "front wheel")
# independent coordinates (all but the pitch) and speeds (lean, steer, rear wheel rates)
INDEPENDENT = ((0, 1, 2, 3, 5, 6, 7), (3, 5, 6))
# rows/columns of lean, steer, lean rate and steer rate in the state (q_i, u_i)
_LEAN_STEER = (3, 4, 7, 8)


def _rot(axis: int, angle):
    """The rotation by `angle` about the coordinate axis `axis` (0, 1, 2)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = jnp.ones_like(c), jnp.zeros_like(c)
    rows = {
        0: [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        1: [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        2: [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return jnp.stack([jnp.stack(r) for r in rows])


def _about(axis, angle):
    """Rodrigues' rotation by `angle` about the unit vector `axis`."""
    k = jnp.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return jnp.eye(3) + jnp.sin(angle) * k + (1.0 - jnp.cos(angle)) * (k @ k)


def _vec(x, y, z):
    return jnp.stack(jnp.broadcast_arrays(*(jnp.asarray(a, float) for a in (x, y, z))))


def poses(q, p: Params) -> dict[str, tuple[jax.Array, jax.Array]]:
    """`(centre of mass, rotation)` of the four bodies, in the paper's axes (x forward,
    y right, z down; the rear contact point at `(x, y, 0)`). The rear frame is turned by
    yaw, lean and pitch (`Rz Rx Ry`) about the rear wheel's centre; the front frame by
    the steer `δ` about the steering axis, tilted back by `λ` and meeting the ground the
    trail `c` ahead of the front contact; the wheels spin about their frames' y axes."""
    lean_frame = _rot(2, q[2]) @ _rot(0, q[3])
    rear = lean_frame @ _rot(1, q[4])
    axis = _vec(jnp.sin(p["lam"]), 0.0, jnp.cos(p["lam"]))
    front = rear @ _about(axis, q[5])
    rear_centre = _vec(q[0], q[1], 0.0) - p["rR"] * lean_frame[:, 2]
    # a point on the steering axis (its ground point at the reference), from the rear centre
    pivot = _vec(p["w"] + p["c"], 0.0, p["rR"])
    steer_origin = rear_centre + rear @ pivot

    def on_front(x, z):  # a point of the front assembly given at the reference
        return steer_origin + front @ (_vec(x, 0.0, z + p["rR"]) - pivot)

    return {
        "rear wheel": (rear_centre, lean_frame @ _rot(1, q[6])),
        "rear frame": (rear_centre + rear @ _vec(p["xB"], 0.0, p["zB"] + p["rR"]), rear),
        "front frame": (on_front(p["xH"], p["zH"]), front),
        "front wheel": (on_front(p["w"], -p["rF"]), front @ _rot(1, q[7])),
    }


def _lowest_point(pose, radius):
    """A knife-edge wheel's lowest point: its centre plus `radius` along the downward
    direction in the wheel's plane, `(e_z − n_z n)/√(1 − n_z²)` with `n` its axle."""
    centre, rot = pose
    n = rot[:, 1]
    down = _vec(0.0, 0.0, 1.0) - n[2] * n
    return centre + radius * down / jnp.sqrt(1.0 - n[2] ** 2)


def front_on_ground(q, p):
    """The holonomic constraint: the front contact point's height, `z_F(q) = 0`."""
    return _lowest_point(poses(q, p)["front wheel"], p["rF"])[2:]


def rolling(q, p):
    """The velocity constraints `A(q) q̇ = 0`, shape `(4, 8)`: no slip of either wheel
    at its contact point `P`, the horizontal rows of the material velocity
    `v_c + ω × (r_P − r_c)`, whose column `j` is `∂r_c/∂q_j + (∂R/∂q_j) Rᵀ (r_P − r_c)`
    (the vertical components follow from the contact geometry)."""

    def wheels(a):
        both = poses(a, p)
        return both["rear wheel"], both["front wheel"]

    def along(tangent):
        return jax.jvp(wheels, (q,), (tangent,))

    (rear, front), (d_rear, d_front) = jax.vmap(along, out_axes=(None, -1))(
        jnp.eye(q.shape[0], dtype=q.dtype)
    )
    contacts = (_vec(q[0], q[1], 0.0), _lowest_point(front, p["rF"]))
    rows = []
    for (centre, rot), (d_centre, d_rot), contact in zip(
        (rear, front), (d_rear, d_front), contacts, strict=True
    ):
        arm = contact - centre
        rows.append((d_centre + jnp.einsum("abj,cb,c->aj", d_rot, rot, arm))[:2])
    return jnp.concatenate(rows, axis=0)


def benchmark_bicycle(**overrides) -> tuple[ConstrainedSystem, dict[str, jax.Array]]:
    """The benchmark (Whipple) bicycle of Meijaard et al. (2007), as `(system, params)`.

    Four [`SpatialBody`][lagrax.bodies.SpatialBody]s (rear wheel, rear frame with rider,
    front frame, front wheel) in the coordinates `q = (x, y, yaw, lean, pitch, steer,
    rear wheel, front wheel)` (`x, y` the rear contact point; the paper's axes: x
    forward, y right, z down, gravity along +z). The front contact on the ground is a
    holonomic constraint; no slip of the two knife-edge wheels (horizontal velocity of
    each wheel's contact point zero) four velocity constraints: a
    [`ConstrainedSystem`][lagrax.ConstrainedSystem] with three degrees of freedom in speed
    (lean, steer, rear wheel rates). Nothing of the paper's closed forms is used.

    `params`: the paper's Table 1 names `w c lam g rR mR IRxx IRyy xB zB mB IBxx IByy IBzz
    IBxz xH zH mH IHxx IHyy IHzz IHxz rF mF IFxx IFyy` (`IRzz = IRxx`, `IFzz = IFxx`),
    defaults the benchmark's values; keyword arguments override them
    (`benchmark_bicycle(mB=60.0, c=0.1)`).

    **Returns:** `(system, params)`; the upright motion at speed `v` is `q = 0`,
    `q̇ = (v, 0, 0, 0, 0, 0, −v/r_R, −v/r_F)`, linearized with
    `independent=((0, 1, 2, 3, 5, 6, 7), (3, 5, 6))` (all coordinates but the pitch; the
    lean, steer and rear wheel rates).

    **Raises:** `ArgumentTypeError` for an unknown parameter name.

    **Example:**

    ```python
    bike, params = lagrax.models.benchmark_bicycle()
    M, C1, K0, K2 = lagrax.models.bicycle_matrices(bike, params)   # the paper's, to 1e-12
    eigs = lagrax.models.bicycle_eigenvalues(bike, params, jnp.linspace(0.0, 10.0, 101))
    ```
    """
    unknown = set(overrides) - set(BENCHMARK)
    if unknown:
        raise ArgumentTypeError(
            f"benchmark_bicycle() got unknown parameters {sorted(unknown)}; known: "
            f"{tuple(BENCHMARK)}"
        )
    params = {k: jnp.asarray(overrides.get(k, v), dtype=float) for k, v in BENCHMARK.items()}
    body = SpatialBody(_masses, _inertias, _all_poses, None)
    gravity = lambda p: _vec(0.0, 0.0, p["g"])  # noqa: E731  (z down)
    free = Scene([body], gravity=gravity, n_dof=8, name="bicycle (four free bodies)").system()
    free = dataclasses.replace(free, coordinate_names=COORDINATES)
    system = ConstrainedSystem(
        free, front_on_ground, velocity_constraints=rolling, name="benchmark bicycle"
    )
    return system, params


_BODIES = ("rear wheel", "rear frame", "front frame", "front wheel")


def _masses(p):
    return jnp.stack([p["mR"], p["mB"], p["mH"], p["mF"]])


def _inertias(p):
    """The four central inertias in body axes (the paper's axes at the reference)."""

    def tensor(xx, yy, zz, xz):
        return jnp.stack([_vec(xx, 0.0, xz), _vec(0.0, yy, 0.0), _vec(xz, 0.0, zz)])

    zero = 0.0 * p["IRxx"]
    return jnp.stack(
        [
            tensor(p["IRxx"], p["IRyy"], p["IRxx"], zero),
            tensor(p["IBxx"], p["IByy"], p["IBzz"], p["IBxz"]),
            tensor(p["IHxx"], p["IHyy"], p["IHzz"], p["IHxz"]),
            tensor(p["IFxx"], p["IFyy"], p["IFxx"], zero),
        ]
    )


def _all_poses(q, p):
    both = poses(q, p)
    return [both[b][0] for b in _BODIES], [both[b][1] for b in _BODIES]


def upright(params: Params, speed) -> tuple[jax.Array, jax.Array]:
    """`(q, q̇)` of the upright steady motion at forward `speed`: everything zero but
    `ẋ = v` and the wheels' rolling rates `−v/r_R`, `−v/r_F` (spinning about +y)."""
    v = jnp.asarray(speed, float)
    zero = jnp.zeros((8,), v.dtype)
    qd = zero.at[0].set(v).at[6].set(-v / params["rR"]).at[7].set(-v / params["rF"])
    return zero, qd


def _linearized(system: ConstrainedSystem, params: Params, speed):
    q, qd = upright(params, speed)
    return system.linearize(q, qd, params, independent=INDEPENDENT)


def bicycle_matrices(system: ConstrainedSystem, params: Params):
    r"""The benchmark's `M, C1, K0, K2` of `M q̈ + v C1 q̇ + (g K0 + v² K2) q = f`,
    `q = (lean φ, steer δ)`, `f = (T_φ, T_δ)`, read off the steady-motion linearization
    ([`ConstrainedSystem.linearize`][lagrax.ConstrainedSystem.linearize] with independent
    coordinates and speeds) at the upright motion at `v = 0` and `v = 1`.

    With the lean and steer rows of the minimal `A = [[0, 1], [−M⁻¹K(v), −M⁻¹C(v)]]` and
    `B` (`M⁻¹` in the lean and steer inputs): `M = (B_{φδ})⁻¹`, `g K0 = −M A_{21}(0)`,
    `K2 = −M A_{21}(1) − g K0`, `C1 = −M A_{22}(1)` (the structure in `v` is exact).

    **Arguments:** `system`, `params` from [`benchmark_bicycle`][lagrax.models.benchmark_bicycle]
    (any parameter values).

    **Returns:** `(M, C1, K0, K2)`, each `(2, 2)`.
    """
    a_rest, b_rest = _linearized(system, params, 0.0)
    a_one, _ = _linearized(system, params, 1.0)
    acc, pos, vel = jnp.array([7, 8]), jnp.array([3, 4]), jnp.array([7, 8])
    mass = jnp.linalg.inv(b_rest[acc][:, jnp.array([3, 5])])
    mass = 0.5 * (mass + mass.T)
    k0 = -mass @ a_rest[acc][:, pos] / params["g"]
    k2 = -mass @ a_one[acc][:, pos] - params["g"] * k0
    c1 = -mass @ a_one[acc][:, vel]
    return mass, c1, k0, k2


def bicycle_eigenvalues(system: ConstrainedSystem, params: Params, speeds) -> jax.Array:
    """The eigenvalues of the upright bicycle at forward `speeds`: those of the lean,
    steer, lean-rate and steer-rate block of the steady-motion linearization (the other
    states, yaw, position and wheel angles and the rear wheel's rate, add zeros).

    **Arguments:** `system`, `params` from [`benchmark_bicycle`][lagrax.models.benchmark_bicycle]
    and `speeds` (m/s), shape `(k,)`; one `vmap` over them (works under `jit`).

    **Returns:** complex, shape `(k, 4)`, each row sorted by real part (then imaginary).
    """
    block = jnp.array(_LEAN_STEER)

    def one(speed):
        a_mat = _linearized(system, params, speed)[0]
        return jnp.sort(jnp.linalg.eigvals(a_mat[block][:, block]))

    return jax.vmap(one)(jnp.asarray(speeds, float).reshape(-1))
