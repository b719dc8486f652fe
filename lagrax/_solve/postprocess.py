r"""A solve's post-processing: what `simulate` and `sweep` compute from the saved states
once the integration is done.

- **One solve** (`simulate`, and each member of a sweep's `keep=` reduction): the
  system's observables at the saves (`observables`), the work of everything that changes
  the Jacobi integral (`power_of`, `work_along`), the scale of the energy error
  (`energy_scale`), and the [`Solution`][lagrax.Solution] they make (`solution`);
  `finish` is the whole tail of `simulate`'s solve (the energy at the saves and the
  result flags, then `solution`).
- **A batch of solves** (a sweep's chunk; every array with a leading member axis):
  `summary`, the energy at the saves, the start and the end, the energy balance and its
  scale as [`Solution.energy_error`][lagrax.Solution.energy_error] computes them, and the
  observables the system reports as a maximum at the final state
  (`AbstractSystem.final_maxima`).

Everything here is traced inside the compiled programs (`jit`, `vmap`, `shard_map`),
never raises, and marks saves that the solve did not reach with `inf`. It asks the system
only through [`AbstractSystem`][lagrax.AbstractSystem], never which kind it is.
"""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
from jaxtyping import Array

from .._core.results import RESULTS
from .solution import Solution

# --------------------------------------------------------------------------- one solve


def finish(
    system, field, args, saves, end, result, stats, started, events=None, work=None
) -> Solution:
    """The [`Solution`][lagrax.Solution] of one solve (the tail of `simulate`'s solve).

    The Jacobi integral `h` and `|T| + |V|` at the saves
    ([`AbstractSystem.energy_and_magnitude`][lagrax.AbstractSystem.energy_and_magnitude];
    `h` is `inf` at unreached saves, like `q` and `q̇`), the result flagged
    `RESULTS.non_finite_state` where a "successful" solve ended in a non-finite state (a
    fixed-step solve that blew up) and `RESULTS.constraint_projection_failed` where the
    initial state could not be formed, then `solution`.

    **Arguments:**

    - `system`, `field`: the system and its `LagrangianVectorField`.
    - `args`: `(params, tau_const)`, the vector field's arguments.
    - `saves`: `(ts, q, qd)` at the saves, `inf` where not reached.
    - `end`: `(t_end, q_end, qd_end)`, the last state the solve reached.
    - `result`, `stats`: the solve's `RESULTS` item and counters.
    - `started`: whether the initial state could be formed
      ([`AbstractSystem.initial_state`][lagrax.AbstractSystem.initial_state]).
    - `events`: the event records, or `None`.
    - `work`: the work at the saves where the loop carried it as state (`WithWork`),
      or `None` (then `work_along` forms it from the saves).

    **Returns:** the `Solution`.
    """
    params = args[0]
    ts, q, qd = saves
    _, q_end, qd_end = end
    energy, magnitude = jax.vmap(lambda s, a, b: system.energy_and_magnitude(s, a, b, params))(
        ts, q, qd
    )
    energy = jnp.where(jnp.isfinite(ts), energy, jnp.inf)  # unreached: inf, like q and qd
    # A fixed-step solve that blows up "succeeds" in diffrax's eyes: flag it.
    finite = jnp.all(jnp.isfinite(q_end)) & jnp.all(jnp.isfinite(qd_end))
    result = RESULTS.where(
        finite | (result != RESULTS.successful), result, RESULTS.non_finite_state
    )
    result = RESULTS.where(started, result, RESULTS.constraint_projection_failed)
    return solution(
        system, field, args, saves, (energy, magnitude), end, result, stats, events, work
    )


def solution(
    system, field, args, saves, energies, end, result, stats, events=None, work=None
) -> Solution:
    """The [`Solution`][lagrax.Solution] of one solve from its saves, their energies and its
    end: the system's `observables`, the work `W` (`work_along`) and the
    `energy_scale` added.

    **Arguments:** as for `finish`, with `energies` `(h, |T| + |V|)` at the saves and
    `result` the final `RESULTS` item.

    **Returns:** the `Solution`.
    """
    params, tau_const = args
    ts, q, qd = saves
    energy, magnitude = energies
    t_end, q_end, qd_end = end
    extras = observables(system, field, params, tau_const, ts, q, qd)
    if work is None:
        work = work_along(system, field, params, tau_const, ts, q, qd)
    scale = energy_scale(ts, energy, magnitude)
    return Solution(
        ts,
        q,
        qd,
        energy,
        result,
        stats,
        t_end,
        q_end,
        qd_end,
        **extras,
        work=work,
        energy_scale=scale,
        events=events,
    )


def energy_scale(ts, energy, magnitude):
    """`max(|h(t_0)|, max_k (|T| + |V|)(t_k))` over the reached saves, from `h` and
    `|T| + |V|` there
    ([`AbstractSystem.energy_and_magnitude`][lagrax.AbstractSystem.energy_and_magnitude]): the
    scale of `Solution.energy_error` (`0` without saves)."""
    if ts.shape[0] == 0:
        return jnp.zeros((), energy.dtype)
    mag = magnitude
    reached = jnp.isfinite(ts) & jnp.isfinite(mag)
    e0 = jnp.where(jnp.isfinite(energy[0]), jnp.abs(energy[0]), 0.0)
    return jnp.maximum(e0, jnp.max(jnp.where(reached, mag, 0.0)))


def power_of(system, field, params, tau_const, t, q, qd):
    """The rate of change of the Jacobi integral along the motion, `−∂L/∂t +
    q̇·(τ + F − ∂D/∂q̇)`, at one state, or `None` when nothing changes `h` (an
    autonomous system without inputs, applied forces or dissipation)."""
    explicit = system.explicit_power(t, q, qd, params)
    inputs = system.input_power(t, q, qd, params, field.tau(t, q, qd, tau_const))
    if explicit is None:
        return inputs
    return explicit if inputs is None else explicit + inputs


class WithWork(eqx.Module):
    r"""The vector field with the work `W = ∫ P dt` as one more state,

    $$
    \frac{d}{dt}\begin{pmatrix} y \\ W \end{pmatrix}
    = \begin{pmatrix} f(t, y, a) \\ P(t, q, v, a) \end{pmatrix},
    \qquad W(t_0) = 0,
    $$

    with `P` the power of `power_of`. A Runge–Kutta step of this system is the step of
    `y` plus the method's own quadrature of `P` along it (nothing of `W` feeds back), so
    `W` is as accurate as the state, and the saves' dense output gives it where they
    fall. The step-size controller sees `y` only (`primal_controller`): the steps are
    those of `y` alone. This is how `simulate`'s plain loop gets its work: the vector
    field is traced once in the program, in the stages, where the Hermite rule of
    `work_along` traced it a second time at the saves (with the power's JVP), for as
    much as a third of a contact scene's compile."""

    field: Any  # the system's LagrangianVectorField

    # `integrate` checks the primal part for non-finite values, projects it and checks
    # its stability (see `integrate.primal_part`)
    augmented = True

    def power(self, t, q, v, args):
        """`P` at one state (`power_of`), of `q`'s dtype."""
        params, tau_const = args
        power = power_of(self.field.system, self.field, params, tau_const, t, q, v)
        return jnp.asarray(power, q.dtype)

    def __call__(self, t, ys, args):
        (q, v), _ = ys
        return self.field(t, (q, v), args), self.power(t, q, v, args)


def relative_work(ts, w):
    """`W(t_k) − W(t_first)` at the saves (from the first reached one, as `work_along`
    gives it; `inf` where not reached), from the integrated work `w` there."""
    reached = jnp.isfinite(ts) & jnp.isfinite(w)
    first = jnp.argmax(reached)
    return jnp.where(reached, w - w[first], jnp.inf)


def no_power(system, field, params, tau_const, t, q, qd) -> bool:
    """Whether nothing changes the Jacobi integral (`power_of` is `None`), found from
    its shape alone (traced aside: nothing of it enters the program)."""
    return jax.eval_shape(lambda: power_of(system, field, params, tau_const, t, q, qd)) is None


def work_along(system, field, params, tau_const, ts, q, qd):
    r"""`W(t_k) = ∫_{t_0}^{t_k} P dt` at the saved times (from the first save; `inf`
    where not reached), with the power `P = −∂L/∂t + q̇·(τ + F − ∂D/∂q̇)` of the explicit
    time dependence, the inputs, the applied force and the dissipation; `None` when
    there is no such power (see `power_of`).

    The rate `P` ([`AbstractSystem.explicit_power`][lagrax.AbstractSystem.explicit_power] plus
    [`AbstractSystem.input_power`][lagrax.AbstractSystem.input_power]) and its first two
    derivatives along the motion at the saves give the two-point Hermite rule

    $$
    W_{k+1} = W_k + \tfrac{Δ}{2}(P_k + P_{k+1})

    + \tfrac{Δ^2}{10}(Ṗ_k − Ṗ_{k+1}) + \tfrac{Δ^3}{120}(P̈_k + P̈_{k+1}),
    $$

    sixth order in the save spacing `Δ`: the saves must resolve the time dependence and
    the inputs (about 15 saves per period of them give ~1e-10), and the inputs must be
    smooth between saves (a switch inside a save interval costs accuracy).

    `Ṗ` is a JVP of `P` along `(1, q̇, q̈)`, with `q̇ = N(q) v` and `q̈ = v̇` from the
    vector field ([`configuration_rate`][lagrax.AbstractSystem.configuration_rate]). `P̈`, the
    derivative of `Ṗ` along the motion, is a central difference of `Ṗ` along the flow
    with the step `ε = ε_mach^{1/3}` times the local save spacing (relative error about
    `ε_mach^{2/3}`, ~4e-11 in float64, where the term it enters is already `O(Δ³)`): two
    more evaluations of the vector field per save, where differentiating the vector
    field itself (a JVP through the equations of motion) cost about as much to run and
    took twice as long to compile (a damped 7-joint URDF arm: 12.7 against 6 s).
    """
    if ts.shape[0] == 0:
        return None
    if no_power(system, field, params, tau_const, ts[0], q[0], qd[0]):
        return None
    reached = jnp.isfinite(ts) & jnp.all(jnp.isfinite(q), axis=1)
    reached = reached & jnp.all(jnp.isfinite(qd), axis=1)
    first = jnp.argmax(reached)  # stand-in values where not reached (masked below)
    ts_s = jnp.where(reached, ts, ts[first])
    q_s = jnp.where(reached[:, None], q, q[first])
    qd_s = jnp.where(reached[:, None], qd, qd[first])

    def rate(t, a, b):  # P, its derivative along the motion Ṗ, q̇ = N(q) v and v̇
        qrate, qdd = field(t, (a, b), (params, tau_const))
        p, dp = jax.jvp(
            lambda c, x, y: power_of(system, field, params, tau_const, c, x, y),
            (t, a, b),
            (jnp.ones_like(t), qrate, qdd),
        )
        return p, dp, qrate, qdd

    h = jnp.diff(ts_s)
    # P̈ = dṖ/dt along the motion: a central difference of Ṗ along the flow,
    # (t, q, q̇) ± ε (1, q̇, q̈), with ε = ε_mach^(1/3) times the local save spacing (the
    # time scale the saves resolve)
    forward = jnp.concatenate([h, h[-1:]]) if h.shape[0] else jnp.ones_like(ts_s)
    backward = jnp.concatenate([h[:1], h]) if h.shape[0] else jnp.ones_like(ts_s)
    spacing = jnp.where(forward > 0, forward, jnp.where(backward > 0, backward, 1.0))
    eps = jnp.finfo(ts_s.dtype).eps ** (1 / 3) * spacing

    def at_save(t, a, b, e):
        """`(P, Ṗ, q̇, q̈)` at the save, then `Ṗ` at `(t, q, q̇) + s ε (1, q̇, q̈)` for
        `s = ±1`: one loop of three evaluations, so that the program holds one copy of
        the vector field here instead of three (each compiled, and each loaded from the
        compilation cache: 0.2-0.3 s for a 7-joint arm)."""

        def point(rates, sign):
            a_rate, b_rate = rates
            step = sign * e  # 0: the save itself (its rates start at zero)
            out = rate(t + step, a + step * a_rate, b + step * b_rate)
            here = sign == 0.0
            rates = (jnp.where(here, out[2], a_rate), jnp.where(here, out[3], b_rate))
            return rates, out

        signs = jnp.asarray([0.0, 1.0, -1.0], e.dtype)
        _, (p, dp, qrate, qdd) = jax.lax.scan(point, (jnp.zeros_like(a), jnp.zeros_like(b)), signs)
        return p[0], dp[0], qrate[0], qdd[0], dp[1], dp[2]

    p, dp, qrate, qdd, dp_plus, dp_minus = jax.vmap(at_save)(ts_s, q_s, qd_s, eps)
    ddp = (dp_plus - dp_minus) / (2 * eps)
    step = (
        0.5 * h * (p[:-1] + p[1:])
        + h**2 / 10.0 * (dp[:-1] - dp[1:])
        + h**3 / 120.0 * (ddp[:-1] + ddp[1:])
    )
    work = jnp.concatenate([jnp.zeros((1,), step.dtype), jnp.cumsum(step)])
    return jnp.where(reached, work, jnp.inf)


def observables(system, field, params, tau_const, ts, q, qd) -> dict[str, Any]:
    """The system's extra observables at the saved states (`inf` where not reached)."""
    out = jax.vmap(
        lambda t, a, b: system.observables(t, a, b, params, field.tau(t, a, b, tau_const))
    )(ts, q, qd)
    reached = jnp.isfinite(ts)
    return {
        k: jnp.where(reached.reshape(reached.shape + (1,) * (v.ndim - 1)), v, jnp.inf)
        for k, v in out.items()
    }


# --------------------------------------------------------------------------- a batch


class Summary(eqx.Module):
    """What `summary` measures per member of a batch of solves (leading axis `M`; `T`
    saves).

    **Fields:**

    - `energy`, `magnitude`: `h` and `|T| + |V|` at the saves, `(M, T)` (`h` is `inf`
      where it is not finite: unreached saves).
    - `energy0`, `energy_end`: `h` at the initial state and at the end, `(M,)`.
    - `energy_balance`, `energy_scale`: the numerator and the denominator of
      [`Solution.energy_error`][lagrax.Solution.energy_error] at the end, `(M,)` (see
      `energy_balance`).
    - `final_maxima`: for each observable named by
      `AbstractSystem.final_maxima`, in that order, its
      largest magnitude over its components at the end state, `max_i |x_i(t_end)|`, `(M,)`.
    """

    energy: Array
    magnitude: Array
    energy0: Array
    energy_end: Array
    energy_balance: Array
    energy_scale: Array
    final_maxima: dict[str, Array]


def summary(system, field, members, tau_const, times, y0s, saves, end, work_end=None) -> Summary:
    """The energies, the energy balance and the final maxima of a batch of solves.

    **Arguments:**

    - `system`, `field`: the system and its `LagrangianVectorField`.
    - `members`: the members' parameters (each leaf with a leading axis `M`).
    - `tau_const`: the constant input shared by the members, or `None`.
    - `times`: `(t0, t1, ts)`, the interval and the save times `(T,)` (`T` may be 0).
    - `y0s`: `(q0, q̇0)`, the initial states the solves started from, `(M, n)` each.
    - `saves`: `(q, q̇)` at `ts`, `(M, T, n)` each, `inf` where not reached.
    - `end`: `(t_end, q_end, q̇_end)`, where each solve ended.
    - `work_end`: the work `W` from `t0` to the end, `(M,)`, where the solves carried
      it as state (`WithWork`), or `None` (then `work_along` forms it from the saves).

    **Returns:** a `Summary`.
    """
    t0, t1, ts = times
    q, qd = saves
    t_end, q_end, qd_end = end
    # the Jacobi integral h at the saves, the start and the end (see Solution.energy)
    # (with |T| + |V| there, for the scale of energy_error)
    energy = jax.vmap(
        jax.vmap(system.energy_and_magnitude, in_axes=(0, 0, 0, None)), in_axes=(None, 0, 0, 0)
    )
    e, mag = energy(ts, q, qd, members) if q.shape[1] else (q[..., 0], q[..., 0])
    e = jnp.where(jnp.isfinite(e), e, jnp.inf)
    q0, qd0 = y0s
    at_start = jax.vmap(system.energy_and_magnitude, in_axes=(None, 0, 0, 0))
    e0, m0 = at_start(t0, q0, qd0, members)
    e_end, m_end = jax.vmap(system.energy_and_magnitude)(t_end, q_end, qd_end, members)
    balance, scale = energy_balance(
        system,
        field,
        members,
        tau_const,
        t0,
        ts,
        q,
        qd,
        (e, mag),
        (q0, qd0, e0, m0),
        (e_end, m_end),
        work_end,
    )
    # the system's observables at the end state, and the largest magnitude of those it
    # reports so (a constrained system: max |φ(q)| and max |A(q) q̇| there)
    at_end = jax.vmap(
        lambda t, a, b, p: system.observables(t, a, b, p, field.tau(t, a, b, tau_const))
    )(jnp.minimum(t_end, t1), q_end, qd_end, members)
    maxima = {k: jnp.max(jnp.abs(at_end[k]), axis=1) for k in system.final_maxima}
    return Summary(e, mag, e0, e_end, balance, scale, maxima)


def energy_balance(
    system, field, members, tau_const, t0, ts, q, qd, saved, start, end, work_end=None
):
    """Per member: the energy balance residual and its scale, as `Solution.energy_error`
    computes them (its numerator and denominator).

    Without inputs, dissipation or time dependence the residual is `h(t_end) − h(t0)`.
    With them it is `h(t_end) − h(t0) − W(t_end)` where the solves carried the work as
    state (`work_end`), else `h − h₀ − W` over the saves (the first to the last reached
    one), `W` the work integrated along them (`sweep` saves internally for that when
    `keep="final"`; NaN when there are no saves). The scale is
    `max(|h(t0)|, |T| + |V|)` over the start, the saves and the end (`h` and
    `|T| + |V|` given there: `saved`, `start`, `end`)."""
    e, mag = saved
    q0, qd0, e0, m0 = start
    e_end, m_end = end
    first = jtu.tree_map(lambda x: x[0], members)
    has_power = not no_power(system, field, first, tau_const, t0, q0[0], qd0[0])
    scale = jnp.maximum(jnp.abs(e0), m0)
    scale = jnp.maximum(scale, jnp.where(jnp.isfinite(m_end), m_end, 0.0))
    if ts.shape[0]:
        reached = jnp.all(jnp.isfinite(q), axis=2)  # (members, T)
        member_ts = jnp.where(reached, ts, jnp.inf)
        scale = jnp.maximum(scale, jax.vmap(energy_scale)(member_ts, e, mag))
    if not has_power:
        return e_end - e0, scale
    if work_end is not None:
        return e_end - e0 - work_end, scale
    if not ts.shape[0]:
        return jnp.full_like(e0, jnp.nan), scale
    work = jax.vmap(lambda p, s, a, b: work_along(system, field, p, tau_const, s, a, b))(
        members, member_ts, q, qd
    )
    ok = jnp.isfinite(work)
    last = ts.shape[0] - 1 - jnp.argmax(ok[:, ::-1], axis=1)
    pick = lambda x: jnp.take_along_axis(x, last[:, None], axis=1)[:, 0]  # noqa: E731
    return pick(e) - e[:, 0] - pick(work), scale
