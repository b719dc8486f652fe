"""The compass-gait walker of Goswami, Thuilot & Espiau (1998), from its energies, as in
`tests/test_periodic.py`: legs of mass `m` at `a` from the foot and `b` from the hip, a
hip of mass `M`, on a slope `slope` [rad]; `q = (θ_ns, θ_s)`, the swing and stance legs'
angles from the upward vertical, positive in the walking direction (down the slope).

The heel strike is the section `θ_ns + θ_s = 2 slope` (upwards), its reset the impact
(an impulse at the swing foot brings it to rest, from the walker with a free stance foot),
then the legs swap roles."""

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx

GOSWAMI = {"m": 5.0, "M": 10.0, "a": 0.5, "b": 0.5, "g": 9.81}
GUESS = (np.array([0.3234, -0.2187]), np.array([0.3772, 1.0918]))  # near the 3° gait


def _points(q, p, foot=(0.0, 0.0)):
    """Stance-leg mass, hip, swing-leg mass, swing foot."""
    ns, s = q[0], q[1]
    a, b = p["a"], p["b"]
    e_s = jnp.stack([jnp.sin(s), jnp.cos(s)])
    e_ns = jnp.stack([jnp.sin(ns), jnp.cos(ns)])
    hip = jnp.stack([foot[0], foot[1]]) + (a + b) * e_s
    return hip - b * e_s, hip, hip - b * e_ns, hip - (a + b) * e_ns


def _kinetic(points):
    def T(q, qd, p):
        vel = jax.jvp(lambda x: points(x, p)[:3], (q,), (qd,))[1]
        masses = (p["m"], p["M"], p["m"])
        return 0.5 * sum(mi * jnp.sum(v**2) for mi, v in zip(masses, vel, strict=True))

    return T


def _potential(q, p):
    heights = [r[1] for r in _points(q, p)[:3]]
    return p["g"] * sum(mi * h for mi, h in zip((p["m"], p["M"], p["m"]), heights, strict=True))


WALKER = lx.LagrangianSystem(_kinetic(_points), _potential, n_dof=2, name="compass gait")
_FREE = lx.LagrangianSystem(
    _kinetic(lambda z, p: _points(z[2:], p, (z[0], z[1]))), lambda z, p: 0.0 * z[0], n_dof=4
)


def _impact(t, q, qd, p):
    qe = jnp.concatenate([jnp.zeros(2), q])
    qde = jnp.concatenate([jnp.zeros(2), qd])
    me = _FREE.mass_matrix(qe, p)
    jac = jax.jacfwd(lambda z: _points(z[2:], p, (z[0], z[1]))[3])(qe)
    kkt = jnp.block([[me, -jac.T], [jac, jnp.zeros((2, 2))]])
    after = jnp.linalg.solve(kkt, jnp.concatenate([me @ qde, jnp.zeros(2)]))[2:4]
    return q[::-1], after[::-1]


HEEL_STRIKE = lx.Event(lambda t, q, qd, p: q[0] + q[1] - 2 * p["slope"], direction=1, reset=_impact)
