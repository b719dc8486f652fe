r"""Joint limits as impacts: events that stop a tree's joints at their limits.

A joint `i` with limits `[lo, hi]` is stopped by an [`Event`][lagrax.Event] whose
condition `min(q_i − lo, hi − q_i)` crosses zero downwards when the joint reaches
either limit. Its reset is the rigid impact of the joint against a stop: an impulse
`Λ` in joint `i` alone (the stop can only push on its own joint), sized by Newton's
law of restitution so that `q̇_i⁺ = −e q̇_i⁻`:

    M Δq̇ = Λ e_i,   Δq̇ = −(1 + e) q̇_i⁻ M⁻¹e_i / (M⁻¹)_ii,

which changes the other joints' rates too, by their coupling through `M`, and takes
the kinetic energy `½ (1 − e²) (q̇_i⁻)² / (M⁻¹)_ii` (all of the energy of the joint's
motion "into" the stop at `e = 0`, none at `e = 1`). The position is clipped onto the
limit (the event's root is found to a few ulps of `t`; the clip makes it exact).

Why events that the user passes, and not events that `simulate` finds on the system:
`simulate`, `sweep` and `periodic_orbit` take events by one argument, whose order is
the order of `Solution.events`; events hidden in the system would shift those indices,
would have to be threaded through every entry point, and would tie the system's
interface (which floating bases are changing) to the tree. A joint limit is an event
like any other: [`limit_events`][lagrax.chains.limit_events] builds them, and they
compose with the user's own (`events=[*limit_events(tree), my_event]`).
"""

import math
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._contact.limits import JointLimit
from .._core.errors import ConfigurationError, ParameterError
from .._solve.events import Event
from .articulated.trees import AbstractTree, Tree
from .floating.system import FloatingTree

LIMIT_MODELS = (None, "impact", "contact")
"""The values of `from_urdf`'s and `from_mjcf`'s `limits=`."""


def _restitution(value: Any, n: int, where: str) -> np.ndarray:
    """`value` as `n` coefficients of restitution in `[0, 1]`, or a `ConfigurationError`."""
    try:
        arr = np.broadcast_to(np.asarray(value, float), (n,))
    except (TypeError, ValueError):
        raise ConfigurationError(
            f"{where}: restitution must be a number in [0, 1] or {n} of them (one per joint), "
            f"got {value!r}"
        ) from None
    bad = ~np.isfinite(arr) | (arr < 0) | (arr > 1)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ConfigurationError(
            f"{where}: restitution[{k}] = {float(arr[k]):g} is not in [0, 1] (0: the joint stops "
            "dead at its limit; 1: it bounces back with its speed)"
        )
    return arr


def with_limits(
    tree: Tree, params: dict, limits: str | None, restitution: Any
) -> tuple[Tree, dict]:
    """`(tree, params)` of a robot file read with `limits=` (`None`, `"contact"`:
    unchanged, the contact scene enforces them; `"impact"`: `params["restitution"]`, one
    coefficient per joint)."""
    if limits not in LIMIT_MODELS:
        raise ConfigurationError(
            f"limits must be None (limits kept in tree.limits, not enforced), 'impact' "
            f"(joints stop at their limits by impacts: lagrax.chains.limit_events) or "
            f"'contact' (compliant stops, with contact=), got {limits!r}"
        )
    if limits in (None, "contact"):
        return tree, params
    lims = np.asarray([tree.limits[b] for b in tree.coordinates], float)
    if not np.any(np.isfinite(lims)):
        raise ConfigurationError(
            "limits='impact', but no joint of the robot has a finite limit: there is "
            "nothing to stop"
        )
    e = _restitution(restitution, tree.n, "limits='impact'")
    return tree, {**params, "restitution": jnp.asarray(e, dtype=params["g"].dtype)}


def contact_limits(robot: Any) -> tuple[JointLimit, ...]:
    """The robot's finite joint limits as the [`JointLimit`][lagrax.contact.JointLimit]s
    of a contact scene (`limits="contact"`), in the tree's coordinate order: a hinge's
    angular, a slide's not; a floating base's joints sit 7 into `q` and 6 into `v`.
    `ConfigurationError` for a tree with ball joints (their coordinates are not one per
    joint)."""
    tree, q0, v0 = _joints(robot)
    if not isinstance(tree, Tree):
        return ()
    if tree.balls:
        raise ConfigurationError(
            "limits='contact' is not read for a tree with ball joints yet (their quaternion "
            "coordinates): load it with limits=None"
        )
    out = []
    for i, body in enumerate(tree.coordinates):
        lo, hi = (float(x) for x in tree.limits[body])
        if math.isfinite(lo) or math.isfinite(hi):
            angular = tree.joint_types[body] != "P"
            name = tree.joint_names[body]
            out.append(JointLimit(q0 + i, lo, hi, v0 + i, angular, name))
    return tuple(out)


def _joints(tree: Any) -> tuple[Any, int, int]:
    """`(joints, q0, v0)`: the tree whose joints carry the limits, and where its
    coordinates start in `q` and in `q̇` (a floating base's `q = (pose 7, joints)`,
    `v = (twist 6, joint rates)`; a fixed-base tree's are its joints')."""
    if isinstance(tree, FloatingTree):
        return tree.tree, 7, 6
    return tree, 0, 0


class _LimitCondition(eqx.Module):
    """`min(q_i − lo, hi − q_i)`: positive inside the limits, zero at either (`index`
    is the joint's place in `q`)."""

    index: int = eqx.field(static=True)
    lower: float = eqx.field(static=True)
    upper: float = eqx.field(static=True)

    def __call__(self, t, q, qd, params):
        x = q[self.index]
        if math.isinf(self.lower):
            return self.upper - x
        if math.isinf(self.upper):
            return x - self.lower
        return jnp.minimum(x - self.lower, self.upper - x)


class _LimitImpact(eqx.Module):
    """The state after joint `index` (its coordinate number) hits a stop with
    restitution `e` (the module docstring's impulse law); the joint sits at `q[q0 +
    index]` and `q̇[v0 + index]` (a floating base: `q0 = 7`, `v0 = 6`)."""

    tree: AbstractTree | FloatingTree
    index: int = eqx.field(static=True)
    lower: float = eqx.field(static=True)
    upper: float = eqx.field(static=True)
    restitution: float | None = eqx.field(static=True)
    q0: int = eqx.field(default=0, static=True)
    v0: int = eqx.field(default=0, static=True)

    def __call__(self, t, q, qd, params):
        i, k = self.q0 + self.index, self.v0 + self.index
        if self.restitution is None:
            if "restitution" not in params:
                raise ParameterError(
                    "limit_events(tree) without restitution= reads params['restitution'] "
                    "(one coefficient per joint, set by from_urdf/from_mjcf with "
                    "limits='impact'), and params has no 'restitution': pass "
                    "restitution=... to limit_events, or load the robot with limits='impact'"
                )
            e = jnp.asarray(params["restitution"], qd.dtype)[self.index]
        else:
            e = jnp.asarray(self.restitution, qd.dtype)
        # the impulse acts where the state goes on: at the stop itself (the located
        # crossing may lie a root tolerance past it), so that the momentum of every
        # other direction is kept with the mass matrix the solve continues with
        q_after = q.at[i].set(jnp.clip(q[i], self.lower, self.upper))
        mass = self.tree.system().mass_matrix(q_after, params)
        x = jnp.linalg.solve(mass, jnp.zeros_like(qd).at[k].set(1.0))  # M⁻¹ e_k
        impulse = -(1 + e) * qd[k] / x[k]
        return q_after, qd + impulse * x


def limit_events(
    tree: AbstractTree | FloatingTree,
    *,
    restitution: Any = None,
    joints: Sequence[str] | None = None,
    max_events: int = 100,
) -> tuple[Event, ...]:
    r"""Events that stop a tree's joints at their limits (`tree.limits`) by impacts.

    One [`lagrax.Event`][] per limited joint (in the order of `joints`, default every
    joint with a finite limit, in the tree's order), to pass to [`lagrax.simulate`][] or
    [`lagrax.sweep`][] (`events=`); its hits are `Solution.events[k]` (times and
    the state just before each impact). The condition `min(q_i − lo, hi − q_i)`
    crosses zero downwards at either limit; the reset applies the impulse of a stop on
    joint `i` alone that reverses its rate times the coefficient of restitution `e`:

    $$
    \dot q^+ = \dot q^- - (1 + e)\,\dot q_i^-\,\frac{M^{-1} e_i}{(M^{-1})_{ii}},
    \qquad \dot q_i^+ = -e\,\dot q_i^-,
    $$

    so the other joints' rates change by their inertial coupling, and the kinetic energy
    falls by `½ (1 − e²) (q̇_i⁻)² / (M⁻¹)_ii` at each hit; `q_i` is clipped onto the
    limit. Effort and velocity limits are not enforced (`tree.effort_limits` are for
    the user's `tau`).

    A joint that gravity (or a torque) holds against its stop bounces ever more often:
    the hits accumulate at a point (a Zeno cascade, `e > 0`) or recur at once (`e =
    0`), and `simulate` ends the solve there with `RESULTS.event_cascade` (a
    `SimulationError` with `throw=True`). Resting against a stop is not modelled.

    **Arguments:**

    - `tree`: a [`Tree`][lagrax.chains.Tree] (from [`lagrax.chains.from_urdf`][] or
      [`lagrax.chains.from_mjcf`][]) or another [`AbstractTree`][lagrax.chains.AbstractTree]
      with `limits`, or a [`FloatingTree`][lagrax.chains.FloatingTree] (from
      `from_urdf(..., floating_base=True)`), whose joints' coordinates are `q[7:]` and
      rates `v[6:]`: a stop's impulse acts on its joint alone, never on the base, so a
      free-floating robot's momentum is the same after a hit as before.
    - `restitution`: the coefficient `e` in `[0, 1]`, a number or one per joint of the
      tree. Default `None`: read at run time from `params["restitution"]` (set by
      `from_urdf`/`from_mjcf` with `limits="impact"`), so a sweep may vary it and
      `jax.grad` differentiates through it.
    - `joints`: names of the joints to stop (default: every joint with a finite limit).
    - `max_events`: the most hits recorded per joint (see [`lagrax.Event`][]).

    **Returns:** a tuple of [`lagrax.Event`][], one per joint in `joints`.

    **Raises:** `ConfigurationError` for a joint name the tree does not have, a joint
    without a finite limit, a tree without limits, or a restitution outside `[0, 1]`;
    `ParameterError` from `simulate` when `restitution=None` and `params` has no
    `"restitution"`.

    **Example:**

    ```python
    tree, params = lagrax.chains.from_urdf("arm.urdf", limits="impact", restitution=0.5)
    events = lagrax.chains.limit_events(tree)
    sol = lagrax.simulate(tree.system(), q0, qd0, params, t1=3.0, events=events)
    sol.events[0].times[: sol.events[0].count]      # when the first limited joint hit
    ```
    """
    joints_tree, q0, v0 = _joints(tree)
    if not isinstance(joints_tree, Tree):
        raise ConfigurationError(
            f"limit_events needs a tree with joint limits (tree.limits), got a "
            f"{type(tree).__name__}"
        )
    n = joints_tree.n
    # per coordinate: a mimic joint is no coordinate (it follows its master, whose limits
    # stop both), so the limits and names of the coordinates' own bodies
    bodies = joints_tree.coordinates
    limits = [joints_tree.limits[b] for b in bodies]
    names = tuple(joints_tree.joint_names[b] for b in bodies)
    finite = [i for i, (lo, hi) in enumerate(limits) if math.isfinite(lo) or math.isfinite(hi)]
    if joints is None:
        chosen = finite
        if not chosen:
            raise ConfigurationError(
                "limit_events: no joint of the tree has a finite limit (tree.limits are all "
                "(-inf, inf)): there is nothing to stop"
            )
    else:
        if isinstance(joints, str):
            joints = [joints]
        chosen = []
        for name in joints:
            if name not in names:
                raise ConfigurationError(
                    f"limit_events: joints names {name!r}, which is not a joint of the tree "
                    f"(joints: {list(names)})"
                )
            i = names.index(name)
            if i not in finite:
                raise ConfigurationError(
                    f"limit_events: joint {name!r} has no finite limit (tree.limits[{i}] = "
                    f"{limits[i]})"
                )
            chosen.append(i)
    e = None if restitution is None else _restitution(restitution, n, "limit_events")
    events = []
    for i in chosen:
        lo, hi = (float(x) for x in limits[i])
        reset = _LimitImpact(tree, i, lo, hi, None if e is None else float(e[i]), q0, v0)
        events.append(
            Event(_LimitCondition(q0 + i, lo, hi), direction=-1, reset=reset, max_events=max_events)
        )
    return tuple(events)
