r"""Natural-parameter continuation of periodic orbits: `continue_orbits`.

Each orbit along the branch is found by [`periodic_orbit`][lagrax.periodic_orbit] from a
secant predictor (the last two orbits extrapolated to the next parameter value), in one
compiled `lax.scan`. Bifurcations are read off the multipliers between neighbouring
orbits, by the sign of test functions that vanish where a multiplier crosses the unit
circle:

- a **fold** (or branch point): a real multiplier through `+1`, `det(DP − I)` changes
  sign; past a fold the branch ends (Newton fails), reported as `"end"`;
- a **period doubling** (flip): a real multiplier through `−1`, `det(DP + I)` changes sign;
- a **Neimark–Sacker** (torus) bifurcation: a complex pair through `|μ| = 1`, the count
  of non-real multipliers outside the unit circle changes.

(`det(DP ± I)` over the full state: with a section the trivial eigenvalue 0 adds a
factor `±1`, which does not change sign.) Folds and period doublings are then located
by the secant method on the test function (each step an orbit solve).
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import checks
from .._core.custom_types import Coordinates, Params, Velocities
from .._core.errors import ArgumentTypeError, ConfigurationError
from .._systems.abstract import AbstractSystem
from .orbit import PeriodicOrbit, SearchConfig, SearchInputs, newton_search, prepare_search


class Bifurcation(eqx.Module):
    """A bifurcation found along a branch of periodic orbits.

    **Fields:**

    - `kind`: `"fold"` (a real multiplier through +1), `"period_doubling"` (through
      −1), `"neimark_sacker"` (a complex pair through the unit circle) or `"end"`
      (the branch could not be continued: Newton failed after a success, typically just
      past a fold).
    - `index`: it lies between `values[index]` and `values[index + 1]`.
    - `value`: the parameter value where it occurs: by the secant method on the test
      function (`refined=True`), or by linear interpolation between the two orbits.
    - `refined`: whether `value` was located by orbit solves (to `tol`) rather than
      interpolated.
    """

    kind: str = eqx.field(static=True)
    index: int = eqx.field(static=True)
    value: float = eqx.field(static=True)
    refined: bool = eqx.field(static=True)


class OrbitBranch(eqx.Module):
    """A branch of periodic orbits over one parameter, from
    [`lagrax.continue_orbits`][].

    **Fields:**

    - `values`: the parameter values, shape `(K,)`.
    - `orbits`: a [`PeriodicOrbit`][lagrax.PeriodicOrbit] whose fields have a leading
      axis `K` (`orbits.multipliers[k]`, `orbits.ok[k]`, …).
    - `bifurcations`: a tuple of [`Bifurcation`][lagrax.Bifurcation], in parameter order.
    """

    values: Float[Array, " K"]
    orbits: PeriodicOrbit
    bifurcations: tuple[Bifurcation, ...]

    @property
    def ok(self) -> Array:
        """Which orbits were found, shape `(K,)`."""
        return self.orbits.ok

    @property
    def stable(self) -> Array:
        """Which orbits are stable, shape `(K,)`."""
        return self.orbits.stable


def _setter(parameter: str | Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    if callable(parameter):
        return parameter
    if isinstance(parameter, str):
        key = parameter

        def set_key(params, value):
            if not isinstance(params, dict) or key not in params:
                raise ConfigurationError(
                    f"parameter={key!r} names an entry of a params dict, but "
                    f"{checks.describe_params(params)}; pass the name of an entry, or a "
                    "function parameter(params, value) -> params"
                )
            return {**params, key: jnp.asarray(value, jnp.result_type(params[key], float))}

        return set_key
    raise ArgumentTypeError(
        "parameter must be the name of an entry of params or a function "
        f"(params, value) -> params, got {type(parameter).__name__}: {parameter!r}"
    )


def _solve_at(cfg: SearchConfig, inp: SearchInputs, set_param, period_of, value, x):
    params = set_param(inp.params, value)
    span = inp.span if period_of is None else jnp.asarray(period_of(params), inp.span.dtype)
    return newton_search(
        cfg, eqx.tree_at(lambda i: (i.x0, i.params, i.span), inp, (x, params, span))
    )[0]


@eqx.filter_jit
def _branch(cfg: SearchConfig, inp: SearchInputs, set_param, period_of, values):
    def step(carry, value):
        x1, v1, x2, v2, have = carry  # the last two orbits found (have: how many)
        slope = jnp.where(v1 != v2, (value - v1) / jnp.where(v1 != v2, v1 - v2, 1.0), 0.0)
        guess = jnp.where(have >= 2, x1 + slope * (x1 - x2), x1)
        orbit = _solve_at(cfg, inp, set_param, period_of, value, guess)
        ok = orbit.ok
        new = (
            jnp.where(ok, orbit.state, x1),
            jnp.where(ok, value, v1),
            jnp.where(ok, x1, x2),
            jnp.where(ok, v1, v2),
            jnp.where(ok, jnp.minimum(have + 1, 2), have),
        )
        return new, orbit

    v0 = values[0]
    init = (inp.x0, v0, inp.x0, v0, jnp.zeros((), jnp.int32))
    _, orbits = jax.lax.scan(step, init, values)
    return orbits


@eqx.filter_jit
def _one(cfg: SearchConfig, inp: SearchInputs, set_param, period_of, value, x):
    return _solve_at(cfg, inp, set_param, period_of, value, x)


def _tests(jacobian: np.ndarray) -> tuple[float, float]:
    """`(det(DP − I), det(DP + I))`."""
    eye = np.eye(jacobian.shape[-1])
    return float(np.linalg.det(jacobian - eye)), float(np.linalg.det(jacobian + eye))


def _complex_outside(mu: np.ndarray) -> int:
    scale = np.maximum(np.abs(mu), 1e-300)
    return int(np.sum((np.abs(mu.imag) > 1e-8 * scale) & (np.abs(mu) > 1)))


def continue_orbits(
    system: AbstractSystem,
    q0: Coordinates,
    qd0: Velocities,
    params: Params,
    parameter: str | Callable[[Any, Any], Any],
    values: Any,
    *,
    section: Any = None,
    period: float | Callable[[Any], Any] | None = None,
    refine: bool = True,
    refine_tol: float = 1e-10,
    **options: Any,
) -> OrbitBranch:
    r"""Follow a periodic orbit as one parameter varies, and report its bifurcations.

    Natural-parameter continuation: the orbit at `values[0]` is found from the guess
    `(q0, q̇0)`, each next one from a secant predictor through the last two orbits found
    (the last one alone at the start, or after a failure). All orbits are found in one
    compiled `lax.scan` of [`periodic_orbit`][lagrax.periodic_orbit]. Then, between
    neighbouring orbits found:

    - `det(DP − I)` changing sign: a real multiplier crossed `+1`, a **fold** (a turning
      point of the branch, where natural continuation ends: the orbits past it are
      reported not `ok`, and a `"end"` bifurcation marks the last orbit found);
    - `det(DP + I)` changing sign: a real multiplier crossed `−1`, a **period doubling**
      (a stable orbit of twice the period is born or dies);
    - the number of non-real multipliers outside the unit circle changing: a
      **Neimark–Sacker** bifurcation (a complex pair crossed `|μ| = 1`).

    With `refine=True` folds and period doublings are located by the secant method on
    `det(DP ∓ I)` as a function of the parameter (each evaluation an orbit solve, from
    the nearer orbit), to `refine_tol`; Neimark–Sacker points are interpolated linearly
    in `|μ| − 1`. This function runs eagerly (it returns a Python list of bifurcations);
    its orbit solves are compiled once.

    **Arguments:**

    - `system`, `q0`, `qd0`, `params`: as for [`periodic_orbit`][lagrax.periodic_orbit]
      (the guess for the first value).
    - `parameter`: the name of an entry of a `params` dict, or a function
      `parameter(params, value) -> params`.
    - `values`: the parameter values, in order (a 1-D array; steps small enough that the
      previous orbits predict the next).
    - `section`, `period`: as for `periodic_orbit`; `period` may be a function
      `period(params)` (a forcing frequency that is the parameter).
    - `refine`, `refine_tol`: locate folds and period doublings by orbit solves.
    - `**options`: `periodic_orbit`'s other options (`t0`, `t_max`, `tol`, `rtol`, …).

    **Returns:** an [`OrbitBranch`][lagrax.OrbitBranch].

    **Raises:** `ConfigurationError` for `values` that are not a non-empty, finite 1-D
    sequence, or a `parameter` name that is not in `params`; `periodic_orbit`'s errors.

    **Example:**

    ```python
    slopes = np.deg2rad(np.linspace(3.0, 5.0, 41))
    branch = lagrax.continue_orbits(walker, q0, qd0, params, "slope", slopes,
                                    section=heel_strike)
    [(b.kind, b.value) for b in branch.bifurcations]
    ```
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size == 0 or not np.all(np.isfinite(values)):
        raise ConfigurationError(
            f"values must be a non-empty, finite 1-D sequence of parameter values, got {values!r}"
        )
    set_param = _setter(parameter)
    period_of = period if callable(period) else None
    first = set_param(params, values[0])
    period0 = period_of(first) if period_of is not None else period
    keys = ("t0", "t_max", "tol", "max_iter", "rtol", "atol", "solver", "max_steps", "events")
    unknown = set(options) - set(keys)
    if unknown:
        raise ConfigurationError(
            f"continue_orbits got unknown options {sorted(unknown)}; it takes "
            f"periodic_orbit's options {list(keys)}"
        )
    opts = dict(
        events=None, t0=0.0, t_max=100.0, tol=None, max_iter=30, rtol=1e-10, atol=1e-10,
        solver=None, max_steps=None,
    )  # fmt: skip
    opts.update(options)
    cfg, inp = prepare_search(
        system, q0, qd0, first, section, period0, opts["events"], opts["t0"], opts["t_max"],
        opts["tol"], opts["max_iter"], opts["rtol"], opts["atol"], opts["solver"],
        opts["max_steps"],
    )  # fmt: skip
    vals = jnp.asarray(values, inp.x0.dtype)
    orbits = _branch(cfg, inp, set_param, period_of, vals)
    bifurcations = _find(cfg, inp, set_param, period_of, values, orbits, refine, refine_tol)
    return OrbitBranch(vals, orbits, tuple(bifurcations))


def _find(cfg, inp, set_param, period_of, values, orbits, refine, refine_tol):
    ok = np.asarray(orbits.ok)
    jac = np.asarray(orbits.jacobian)
    mu = np.asarray(orbits.multipliers)
    states = np.asarray(orbits.state)
    found = []
    for k in range(len(values) - 1):
        if ok[k] and not ok[k + 1]:
            found.append(Bifurcation("end", k, float(values[k]), False))
            continue
        if not (ok[k] and ok[k + 1]):
            continue
        (fa, pa), (fb, pb) = _tests(jac[k]), _tests(jac[k + 1])
        for kind, a, b, sign in (("fold", fa, fb, -1.0), ("period_doubling", pa, pb, 1.0)):
            if np.sign(a) != np.sign(b) and a != 0:
                value = values[k] + a / (a - b) * (values[k + 1] - values[k])
                refined = False
                if refine:
                    value, refined = _secant(
                        cfg, inp, set_param, period_of, values[k], values[k + 1], a, b,
                        states[k], states[k + 1], sign, refine_tol,
                    )  # fmt: skip
                found.append(Bifurcation(kind, k, float(value), refined))
        na, nb = _complex_outside(mu[k]), _complex_outside(mu[k + 1])
        if na != nb:
            ra = np.max(np.abs(mu[k][np.abs(mu[k].imag) > 0]), initial=1.0) - 1
            rb = np.max(np.abs(mu[k + 1][np.abs(mu[k + 1].imag) > 0]), initial=1.0) - 1
            w = ra / (ra - rb) if ra != rb else 0.5
            found.append(
                Bifurcation(
                    "neimark_sacker",
                    k,
                    float(values[k] + np.clip(w, 0, 1) * (values[k + 1] - values[k])),
                    False,
                )
            )
    return found


def _secant(cfg, inp, set_param, period_of, va, vb, fa, fb, xa, xb, sign, tol):
    """The root of `det(DP + sign I)` in the parameter between `va` and `vb` (where it
    changes sign), by the Illinois variant of regula falsi: `(value, converged)`."""
    dtype = inp.x0.dtype
    side, previous = 0, np.inf
    for _ in range(40):
        v = vb - fb * (vb - va) / (fb - fa)
        if abs(v - previous) <= tol * max(1.0, abs(v)):
            return v, True
        previous = v
        x = xa + (v - va) / (vb - va) * (xb - xa)
        orbit = _one(cfg, inp, set_param, period_of, jnp.asarray(v, dtype), jnp.asarray(x))
        if not bool(orbit.ok):
            return v, False
        jac = np.asarray(orbit.jacobian)
        f = float(np.linalg.det(jac + sign * np.eye(jac.shape[0])))
        state = np.asarray(orbit.state)
        if abs(vb - va) <= tol * max(1.0, abs(v)) or f == 0:
            return v, True
        if np.sign(f) == np.sign(fb):
            vb, fb, xb = v, f, state
            if side == 1:
                fa /= 2
            side = 1
        else:
            va, fa, xa = v, f, state
            if side == -1:
                fb /= 2
            side = -1
    return v, abs(vb - va) <= 1e3 * tol * max(1.0, abs(v))
