r"""How a Poincaré section serves [`lagrax.periodic_orbit`][] from a state, and, where it
cannot, why.

The return map is `P(x) = R(φ(τ(x), x))`: the flow to the next crossing of
`g(t, q, q̇) = 0` (in the section's `direction`), then the reset `R` (the identity
without one). Its fixed point lies in the image of `R`:

- **on the section** where `R` maps the section into itself (no reset; a walker's leg
  swap with the section `φ1 + φ2 + 2γ = 0`). Then the guess and each Newton iterate are
  projected onto `g = 0` (along `∇g`), and a start that round-off puts on the near side
  of the section is not counted as a crossing;
- **just after the reset** where `R`'s image is off the section (a guarded heel strike,
  `jnp.where(swing leg ahead, foot height, 1.0)`: the condition is `1` after the legs
  swap). The map `x⁺ ↦ R(flow to the next crossing)` is used as it is: no projection
  (`∇g` may be `0` there), and its fixed point is the state just after the strike.

A section cannot serve when the guess is where the condition is constant (`∇g = 0`) and
there is no reset (the fixed point is on `g = 0`, and the guess cannot be brought there),
or when the guess is on the section while the reset's image is not (the guess is a
pre-reset state, the fixed point a post-reset one). `check_guess` says so eagerly;
`crossing_message` explains a search that failed because the motion first crosses the
section the other way.
"""

from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .._core.errors import PeriodicOrbitError
from .._solve.events import Event
from .._solve.simulate import simulate
from .._systems.abstract import AbstractSystem

ON_SECTION = 1e-8  # |g| / (|∇g| max(1, |x|)): a state on the section, to round-off
WORDS = {0: "either way", 1: "upwards", -1: "downwards"}


class SectionAt(NamedTuple):
    """The section seen from a state `x = (q, q̇)` at `t0` (arrays; traced under `jit`)."""

    value: Array  # g(t0, x)
    grad_norm: Array  # |∇g(t0, x)|, with respect to x
    onto: Array  # x projected onto g = 0 (x itself where ∇g = 0)
    image_value: Array  # g at the reset's image of `onto` (g(onto) without a reset)
    image_grad_norm: Array  # |∇g| there
    project: Array  # the projection is sound: ∇g ≠ 0, and R maps the section into itself
    unusable: Array  # no return map can start from x (see the module's docstring)


def _condition(section: Event, t0, params, n: int):
    def g(y):
        return jnp.asarray(section.condition(t0, y[:n], y[n:], params), y.dtype)

    return g


def project(section: Event, t0, x, params):
    """`x` projected onto `g(t0, x) = 0` by three Gauss–Newton steps along `∇g`
    (unchanged where `∇g = 0`)."""
    g = _condition(section, t0, params, x.shape[0] // 2)
    for _ in range(3):
        value, grad = jax.value_and_grad(g)(x)
        norm2 = jnp.sum(grad**2)
        x = jnp.where(norm2 > 0, x - value * grad / jnp.where(norm2 > 0, norm2, 1.0), x)
    return x


def analyse(section: Event, t0, x, params) -> SectionAt:
    """The section seen from `x`: whether to project onto it, and whether it can serve."""
    n = x.shape[0] // 2
    g = _condition(section, t0, params, n)
    value, grad = jax.value_and_grad(g)(x)
    norm = jnp.sqrt(jnp.sum(grad**2))
    onto = project(section, t0, x, params)
    image = onto
    if section.reset is not None:
        q1, qd1 = section.reset(t0, onto[:n], onto[n:], params)
        image = jnp.concatenate([jnp.reshape(q1, (n,)), jnp.reshape(qd1, (n,))]).astype(x.dtype)
    image_value, image_grad = jax.value_and_grad(g)(image)
    image_norm = jnp.sqrt(jnp.sum(image_grad**2))

    def on(v, gn, y):
        return (gn > 0) & (jnp.abs(v) <= ON_SECTION * gn * jnp.maximum(1.0, jnp.max(jnp.abs(y))))

    if section.reset is None:
        project_ok = norm > 0
        unusable = norm == 0
    else:
        # the image as near the section as the projection got (a rough guess far from a
        # curved section: three Gauss–Newton steps leave a residual that R carries over)
        left, left_grad = jax.value_and_grad(g)(onto)
        left_norm = jnp.sqrt(jnp.sum(left_grad**2))
        off = jnp.abs(left) / jnp.where(left_norm > 0, left_norm, 1.0)
        near = (left_norm > 0) & (jnp.abs(image_value) <= 10 * off * image_norm)
        image_on = (image_norm > 0) & (on(image_value, image_norm, image) | near)
        project_ok = (norm > 0) & image_on
        unusable = on(value, norm, x) & ~image_on
    return SectionAt(value, norm, onto, image_value, image_norm, project_ok, unusable)


_analyse_jit = eqx.filter_jit(analyse)


def describe(section: Event) -> str:
    """`the section <condition> (crossing upwards, direction=+1, reset <reset>)`."""

    def name(fn):
        return getattr(fn, "__qualname__", None) or type(fn).__name__

    reset = f", reset {name(section.reset)}" if section.reset is not None else ", no reset"
    return (
        f"the section {name(section.condition)} (crossing {WORDS[section.direction]}, "
        f"direction={section.direction:+d}{reset})"
    )


def check_guess(section: Event, t0, x, params) -> None:
    """Eagerly, a `PeriodicOrbitError` where the section cannot serve from the guess `x`:
    `∇g = 0` without a reset, or the guess on the section and the reset's image off it."""
    at = _analyse_jit(section, t0, x, params)
    if not bool(at.unusable):
        return
    value = float(at.value)
    if section.reset is None:
        raise PeriodicOrbitError(
            f"periodic_orbit cannot use {describe(section)} from the guess: the condition "
            f"is constant there (value {value:.6g}, gradient ∇g = 0 with respect to (q, qd): "
            "a guard, such as jnp.where(..., height, 1.0), that is off), and without a "
            "reset the orbit's fixed point lies on the section g = 0, which the guess "
            "cannot be projected onto. Start from a state on or near the section, where the "
            "condition varies (e.g. a crossing recorded by simulate's events), or give the "
            "impact as the section's reset: the fixed point is then the state just after it"
        )
    flat = "∇g = 0" if float(at.image_grad_norm) == 0 else f"|∇g| = {float(at.image_grad_norm):.3g}"
    raise PeriodicOrbitError(
        f"periodic_orbit cannot start from this guess with {describe(section)}: the guess "
        f"is on the section (condition {value:.3g}, |∇g| = {float(at.grad_norm):.3g}) but "
        f"the reset's image is not (the condition is {float(at.image_value):.6g} there, "
        f"{flat}), so the return map (the flow to the next crossing, then the reset) has "
        "its fixed point at the state just after the reset; from a state on the section "
        "the flow runs on past the crossing. Pass the post-reset state as the guess: "
        "q0, qd0 = section.reset(t0, q0, qd0, params)"
    )


def first_crossing(system: AbstractSystem, section: Event, t0, t1, x, params, **solve: Any):
    """The motion's first crossing of the section from `x`, either way, eagerly:
    `(direction, t, q, q̇, ġ)` (the condition's rate `ġ` there), or `None` before `t1`."""
    n = x.shape[0] // 2
    d = section.direction or 1
    watch = [Event(section.condition, direction=s, terminal=True) for s in (d, -d)]
    sol = simulate(
        system, x[:n], x[n:], params, t0=t0, t1=t1, n_save=2, events=watch, throw=False,
        **solve,
    )  # fmt: skip
    hits = [(float(r.times[0]), s) for r, s in zip(sol.events, (d, -d), strict=True)]
    hits = [h for h in hits if np.isfinite(h[0])]
    if not hits:
        return None
    t, s = min(hits)
    q, qd = sol.q_end, sol.qd_end
    qdd = system.accelerations(sol.t_end, q, qd, params, None)
    rate = jax.jvp(
        lambda tt, a, b: section.condition(tt, a, b, params),
        (sol.t_end, q, qd),
        (jnp.ones_like(sol.t_end), qd, qdd),
    )[1]
    return s, t, np.asarray(q), np.asarray(qd), float(rate)


def crossing_message(crossing, section: Event, why: str) -> str | None:
    """Why the section failed where the motion first crosses it the other way (`None`
    where `crossing` is in the section's direction, or there is none)."""
    if crossing is None or section.direction == 0 or crossing[0] == section.direction:
        return None
    s, t, q, qd, rate = crossing
    other = -section.direction
    return (
        f"periodic_orbit: with {describe(section)}, the motion from the guess first "
        f"crosses the section {WORDS[s]}, at t = {t:.6g} (q={q.tolist()}, qd={qd.tolist()}, "
        f"where the condition's rate is ġ = {rate:.6g}), a crossing that "
        f"direction={section.direction:+d} does not count, so the return map runs on past "
        f"it ({why}). If that crossing is the event (a heel strike), give "
        f"direction={other:+d}; otherwise start from a state past it"
    )
