"""A vertical disk rolling without slipping: velocity (non-holonomic) constraints.

The disk (radius R, mass m) is held upright on a plane. Its configuration is
q = (x, y, θ, φ): the contact point (x, y), the heading θ and the spin angle φ. Rolling
without slipping says the contact point moves along the heading at the rim speed,

    ẋ = R φ̇ cos θ,   ẏ = R φ̇ sin θ,     i.e.  A(q) q̇ = 0,

a constraint on velocities that no φ(q) = 0 integrates: the disk can reach any (x, y, θ, φ)
(parallel parking), yet never slides sideways. lagrax takes A(q) as it is
(``velocity_constraints=``) and solves the constrained equations with the Lagrange
multipliers μ, here the friction force the ground exerts on the disk.

Two runs: the free disk, which rolls on a circle of radius R Ω/ω (Ω the spin, ω the turn
rate; both constant), drawn over that circle; and a disk driven on its axle while a
steering torque 0.12 cos(1.5 t) swings its heading, which snakes across the plane.

    python examples/rolling_disk.py            # writes rolling_disk.png
"""

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import lagrax as lx  # noqa: E402


def kinetic(q, qd, p):
    # translation of the centre (above the contact point) + spin about the axle
    # (½ m R²) + turning about a vertical diameter (¼ m R²)
    m, r = p["m"], p["R"]
    return 0.5 * m * (qd[0] ** 2 + qd[1] ** 2) + 0.125 * m * r**2 * (qd[2] ** 2 + 2 * qd[3] ** 2)


def potential(q, p):
    return 0.0 * q[0]  # the centre stays at height R: gravity does no work


def rolling(q, p):
    """A(q), shape (2, 4): the rows of ẋ − R cos θ φ̇ = 0 and ẏ − R sin θ φ̇ = 0."""
    c, s, zero, one = jnp.cos(q[2]), jnp.sin(q[2]), 0.0 * q[0], 1.0 + 0.0 * q[0]
    return jnp.stack(
        [jnp.stack([one, zero, zero, -p["R"] * c]), jnp.stack([zero, one, zero, -p["R"] * s])]
    )


free = lx.LagrangianSystem(kinetic, potential, n_dof=4, name="disk")
disk = lx.ConstrainedSystem(free, velocity_constraints=rolling, name="rolling disk")
params = {"m": 2.0, "R": 0.3}
R = params["R"]

# 1. free rolling: spin Ω = 8 rad/s, turn rate ω = 0.6 rad/s -> a circle of radius R Ω/ω
spin, turn = 8.0, 0.6
q0 = np.array([0.0, 0.0, 0.0, 0.0])
qd0 = np.array([R * spin, 0.0, turn, spin])  # admissible: ẋ = R φ̇ cos 0
free_sol = lx.simulate(disk, q0, qd0, params, t1=2 * np.pi / turn, n_save=400)
radius = R * spin / turn
print(
    f"free disk: radius {radius:.4f} m expected; path's distance from the centre "
    f"(0, {radius:.2f}) within {np.ptp(np.hypot(free_sol.q[:, 0], free_sol.q[:, 1] - radius)):.1e}"
)


# 2. driven and steered: a constant axle torque and a steering torque 0.12 cos(1.5 t)
def torques(t, q, qd):
    return jnp.stack([0.0 * t, 0.0 * t, 0.12 * jnp.cos(1.5 * t), 0.02 + 0.0 * t])


# the steering torque alone gives θ(t) = θ0 + (0.12/(1.5² I_turn)) (1 − cos 1.5 t): start at
# θ0 = −0.12/(1.5² I_turn) so the heading swings about the x axis (I_turn = ¼ m R²)
th0 = -0.12 / (1.5**2 * 0.25 * params["m"] * R**2)
q0_steer = np.array([0.0, 0.0, th0, 0.0])
qd0_steer = np.array([R * np.cos(th0), R * np.sin(th0), 0.0, 1.0])  # rolling at 1 rad/s
steer_sol = lx.simulate(disk, q0_steer, qd0_steer, params, t1=20.0, n_save=800, tau=torques)
print(
    f"steered disk: max |A(q) qd| = {np.abs(steer_sol.velocity_constraint_violation).max():.1e}, "
    f"largest friction force {np.abs(steer_sol.multipliers).max():.3f} N"
)

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.6), width_ratios=[1, 2.2])
angle = np.linspace(0, 2 * np.pi, 200)
ax1.plot(
    radius * np.sin(angle), radius * (1 - np.cos(angle)), color="0.8", lw=6, label="circle R Ω/ω"
)
ax1.plot(free_sol.q[:, 0], free_sol.q[:, 1], color="C0", label="lagrax")
ax1.set_title("free disk: constant spin and turn rate")
ax2.plot(steer_sol.q[:, 0], steer_sol.q[:, 1], color="C1")
# the heading every so often, as short ticks along the track
k = slice(0, None, 40)
ax2.quiver(
    steer_sol.q[k, 0],
    steer_sol.q[k, 1],
    np.cos(steer_sol.q[k, 2]),
    np.sin(steer_sol.q[k, 2]),
    angles="xy",
    width=0.004,
    color="C1",
)
ax2.set_title("driven axle, steering torque 0.12 cos(1.5 t)")
for ax in (ax1, ax2):
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
ax1.legend(loc="center")
fig.suptitle("Vertical disk rolling without slipping: ground track of the contact point")
fig.tight_layout()
fig.savefig("rolling_disk.png", dpi=110)
print("wrote rolling_disk.png")
