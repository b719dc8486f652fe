r"""Stability maps: `orbit_map`, periodic orbits over a parameter grid as a Dataset.

Every member's orbit is found by the search of [`periodic_orbit`][lagrax.periodic_orbit]
in one compiled program (`jax.lax.map` over batches under `jax.vmap`); the result is
labelled as [`lagrax.sweep`][]'s: the dimensions and coordinates of a [`lagrax.grid`][]
(or `"member"` for [`lagrax.samples`][] and batched parameters).
"""

import json
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.custom_types import Params
from .._core.errors import ConfigurationError
from .._core.results import code_of, messages
from .._solve.events import Event
from .._sweep.dataset import member_labels, short_label, statuses
from .._sweep.driver import dof_labels
from .._sweep.grid import Grid, Members
from .._systems.abstract import AbstractSystem
from .orbit import SearchConfig, SearchInputs, newton_search, prepare_search

_OPTIONS = ("t0", "t_max", "tol", "max_iter", "rtol", "atol", "solver", "max_steps", "events")


@eqx.filter_jit
def _solve_all(cfg: SearchConfig, inp: SearchInputs, period_of, x0s, params, batch_size: int):
    def one(member):
        x0, p = member
        span = inp.span if period_of is None else jnp.asarray(period_of(p), inp.span.dtype)
        return newton_search(
            cfg, eqx.tree_at(lambda i: (i.x0, i.params, i.span), inp, (x0, p, span))
        )[0]

    n = x0s.shape[0]
    if batch_size >= n:
        return jax.vmap(lambda x0, p: one((x0, p)))(x0s, params)
    return jax.lax.map(one, (x0s, params), batch_size=batch_size if batch_size > 1 else None)


def orbit_map(
    system: AbstractSystem,
    q0: Any,
    qd0: Any,
    params: Grid | Params,
    *,
    section: Event | None = None,
    period: float | Callable[[Any], Any] | None = None,
    batch_size: int = 1,
    **options: Any,
):
    r"""Periodic orbits and their stability over a batch of parameters: a stability map
    as a labelled `xarray.Dataset`.

    For every member (a point of a [`lagrax.grid`][], a draw of [`lagrax.samples`][], or
    one entry along the leading axis of batched `params`), the periodic orbit near the
    guess is found as by [`periodic_orbit`][lagrax.periodic_orbit] (Newton on the return
    map, `DP` by forward-mode derivatives through `simulate`), all members in one compiled
    program: `batch_size` members at a time under `jax.vmap`, the batches one after
    another (`jax.lax.map`). A member whose search fails reports it in its own `result`, `ok` and
    `status`; nothing is raised for it.

    **Arguments:**

    - `system`: the model.
    - `q0`, `qd0`: the guess, shared `(n,)` or one per member (`(members, n)`, or the
      grid's shape then `n`). A grid's `q0_i` / `qd0_i` axes set components of it.
    - `params`: a [`lagrax.Grid`][] (from `grid` or `samples`), or parameters whose
      every leaf has a leading member axis.
    - `section`, `period`: as for `periodic_orbit` (exactly one); `period` may be a
      function `period(params)` of each member's parameters (a swept forcing frequency).
    - `batch_size`: how many members are solved together under `vmap` (default 1: one
      after another). Under `vmap` every member waits for the slowest one's solver steps
      and Newton steps (a walker that falls runs to `t_max` or `max_steps`): on a CPU one
      at a time is much faster (the compass gait's map: ~40× per orbit); on a GPU a batch of
      thousands uses its width.
    - `**options`: `periodic_orbit`'s other options (`t0`, `t_max`, `tol`, `max_iter`,
      `rtol`, `atol`, `solver`, `max_steps`, `events`), shared by all members.

    **Returns:** an `xarray.Dataset` with the sweep's dimensions (the grid's names, or
    `"member"`) and its coordinates (the swept values, with their units), plus `dof`
    (the system's coordinate names or `0 … n−1`) and `multiplier` (`0 … k−1`, by
    decreasing modulus). Variables, per member:

    - `q`, `qd` `(…, dof)`: the fixed point (`NaN` where the orbit was not found);
    - `period` [s]: the return time (with a section) or the period (`NaN` where not found);
    - `multipliers` `(…, multiplier)`, complex: the Floquet multipliers, as
      `PeriodicOrbit.multipliers` (`NaN` where not found); `max_multiplier`: the largest
      modulus `max |μ|` (the orbit is stable below 1);
    - `stable`, `ok` (bool); `result` (the [`lagrax.RESULTS`][] code) and `status`
      (`"ok"` or the failure's message); `iterations` (Newton steps) and `residual`
      (`‖P(x) − x‖_∞`).

    `attrs`: `n_members`, `n_failed`, `n_stable`, `failures` (a JSON count of the
    failures by message), `rtol`, `atol` and `tol`.

    **Raises:** `periodic_orbit`'s errors for a bad section, period or option (checked on
    the first member; a section that a member's motion never crosses is reported in its
    `result`, `orbit_no_return`, not raised); `ConfigurationError` for an unknown option;
    `grid`'s and `sweep`'s errors for parameters or guesses without members or of the
    wrong shape.

    **Example:**

    ```python
    walkers = lx.grid(params, slope=np.deg2rad(np.linspace(1, 5, 32)),
                      M=np.linspace(2.5, 20, 32), units={"slope": "rad", "M": "kg"})
    ds = lx.orbit_map(walker, q0, qd0, walkers, section=heel_strike)
    ds.max_multiplier.plot()   # over (slope, M); ds.stable.mean() is the stable share
    ```
    """
    unknown = set(options) - set(_OPTIONS)
    if unknown:
        raise ConfigurationError(
            f"orbit_map got unknown options {sorted(unknown)}; it takes periodic_orbit's "
            f"options {list(_OPTIONS)}"
        )
    opts: dict[str, Any] = dict(
        events=None, t0=0.0, t_max=100.0, tol=None, max_iter=30, rtol=1e-10, atol=1e-10,
        solver=None, max_steps=None,
    )  # fmt: skip
    opts.update(options)
    if (
        not isinstance(batch_size, (int, np.integer))
        or isinstance(batch_size, bool)
        or (batch_size < 1)
    ):
        raise ConfigurationError(f"batch_size must be a positive integer, got {batch_size!r}")
    members = Members.of(params, q0, qd0)
    first = members.first()
    period_of = period if callable(period) else None
    period0 = period_of(first) if period_of is not None else period
    cfg, inp = prepare_search(
        system, members.q0s[0], members.qd0s[0], first, section, period0, opts["events"],
        opts["t0"], opts["t_max"], opts["tol"], opts["max_iter"], opts["rtol"],
        opts["atol"], opts["solver"], opts["max_steps"],
    )  # fmt: skip
    dtype = inp.x0.dtype
    x0s = jnp.concatenate([jnp.asarray(members.q0s), jnp.asarray(members.qd0s)], axis=1)
    batched = jax.tree_util.tree_map(
        lambda v, f: jnp.asarray(v, jnp.result_type(jnp.asarray(f).dtype, v)),
        members.params_of(),
        first,
    )
    orbits = _solve_all(cfg, inp, period_of, x0s.astype(dtype), batched, int(batch_size))

    return _map_dataset(system, members, orbits, inp)


def _map_dataset(system: AbstractSystem, members: Members, orbits: Any, inp: Any):
    """The stability map as a labelled `xarray.Dataset`: each member's orbit (NaN where
    none was found), its multipliers and stability, how the search ended, and the
    failures counted by kind."""
    import xarray as xr

    shape = members.shape
    dims = list(members.dims)

    def shaped(x):
        x = np.asarray(x)
        return x.reshape(shape + x.shape[1:])

    ok = np.asarray(orbits.ok)
    found = ok[:, None]
    mu = np.where(found, np.asarray(orbits.multipliers), np.nan)
    result = np.asarray(code_of(orbits.result)).astype(np.int64)
    n = members.q0s.shape[1]
    data = {
        "q": (dims + ["dof"], shaped(np.where(found, orbits.q, np.nan)), {"long_name": "q*"}),
        "qd": (dims + ["dof"], shaped(np.where(found, orbits.qd, np.nan)), {"long_name": "q̇*"}),
        "period": (
            dims,
            shaped(np.where(ok, orbits.period, np.nan)),
            {"units": "s", "long_name": "period"},
        ),
        "multipliers": (dims + ["multiplier"], shaped(mu), {"long_name": "Floquet multiplier"}),
        "max_multiplier": (
            dims,
            shaped(np.max(np.abs(mu), axis=-1)),
            {"long_name": "largest |Floquet multiplier|"},
        ),
        "stable": (dims, shaped(np.asarray(orbits.stable))),
        "ok": (dims, shaped(ok)),
        "result": (dims, shaped(result)),
        "status": (dims, shaped(statuses(result))),
        "iterations": (dims, shaped(np.asarray(orbits.iterations)), {"long_name": "Newton steps"}),
        "residual": (dims, shaped(np.asarray(orbits.residual))),
    }
    coords: dict[str, Any] = {
        "dof": dof_labels(system.coordinate_names, n),
        "multiplier": np.arange(mu.shape[-1]),
        **member_labels(members),
    }
    text = messages()
    counts = {short_label(text[c]): int(np.sum(result == c)) for c in np.unique(result[~ok])}
    attrs = dict(
        n_members=int(members.size),
        n_failed=int(np.sum(~ok)),
        n_stable=int(np.sum(np.asarray(orbits.stable))),
        failures=json.dumps(counts),
        rtol=float(inp.rtol),
        atol=float(inp.atol),
        tol=float(inp.tol),
    )
    return xr.Dataset(data, coords=coords, attrs=attrs)
