"""The lecture's mass–spring–damper, `m ẍ + c ẋ + k x = f(t)`."""

import jax.numpy as jnp

from .._core.checks import physical
from .._core.errors import ArgumentTypeError
from .._systems.lagrangian import LagrangianSystem


def _kinetic(q, qd, p):
    return 0.5 * p["m"] * qd[0] ** 2


def _potential(q, p):
    return 0.5 * p["k"] * q[0] ** 2


def _dissipation(q, qd, p):
    return 0.5 * p["c"] * qd[0] ** 2


def _harmonic_force(t, q, qd, p):
    return jnp.reshape(p["f0"] * jnp.cos(p["omega"] * t), (1,))


def mass_spring_damper(**overrides):
    """A mass on a linear spring and viscous damper, as `(system, params)`.

    `T = ½ m ẋ²`, `V = ½ k x²`, Rayleigh `D = ½ c ẋ²` and a harmonic load
    `f(t) = f0 cos(ω t)` give `m ẍ + c ẋ + k x = f(t)`. `params` keys:
    `m k c f0 omega` (defaults 1, 1, 0, 0, 1: an undamped, unforced unit oscillator).
    For any other `f(t)`, pass `tau=` to [`lagrax.simulate`][].
    """
    params = {"m": 1.0, "k": 1.0, "c": 0.0, "f0": 0.0, "omega": 1.0}
    unknown = set(overrides) - set(params)
    if unknown:
        raise ArgumentTypeError(f"mass_spring_damper() got unknown parameters {sorted(unknown)}")
    params.update(overrides)
    params = {k: jnp.asarray(v, dtype=float) for k, v in params.items()}
    physical(params["m"], "mass_spring_damper m")
    system = LagrangianSystem(
        _kinetic,
        _potential,
        dissipation=_dissipation,
        force=_harmonic_force,
        n_dof=1,
        name="mass-spring-damper",
    )
    return system, params
