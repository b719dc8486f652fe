"""A sweep's observables (`sweep(..., observables=)`): the system's
[`observables`][lagrax.AbstractSystem.observables] (a `ContactSystem`'s contact gaps and
forces, a constrained system's violations and multipliers) kept per member at the kept
times, or at the end with `keep="final"`, as the Dataset's variables.

- `observables_option`: the option, checked on the host against what the system reports
  (by name), with each one's dimension names
  ([`observable_dims`][lagrax.AbstractSystem.observable_dims]).
- `observe`: inside the compiled chunk, the observables of a batch of solves, as
  `simulate`'s [`Solution`][lagrax.Solution] has them (`postprocess.observables`).
"""

import difflib
from typing import Any

import jax
import jax.numpy as jnp

from .._core.errors import ArgumentTypeError, ConfigurationError
from .._solve.postprocess import observables
from .._systems.vector_field import LagrangianVectorField
from .result import NamedArrays

Observed = tuple[tuple[str, tuple[str, ...]], ...]


def observables_option(system, tau_fn, probe: tuple, requested: Any, keep: Any) -> Observed:
    """`observables=` as `((name, dims), ...)`: `False`/`None`/`()` (none), `True` (every
    observable the system reports), a name, or a sequence of names.

    `tau_fn` is the solve's input function; `probe` is `(t0, q0, q̇0, params,
    tau_const)` of one member, to learn (traced, not
    evaluated) which observables the system reports and their shapes.

    **Raises:** `ArgumentTypeError` for a value of the wrong kind; `ConfigurationError`
    for a name the system does not report, one it reports as a final maximum
    (`AbstractSystem.final_maxima`: a variable of that name already), or observables
    with a `keep=` reduction (its `Solution` carries them already).
    """
    if requested is None or requested is False:
        return ()
    t0, q0, qd0, params, tau_const = probe
    field = LagrangianVectorField(system, tau_fn)
    t0 = jnp.asarray(t0, jnp.asarray(q0).dtype)
    q0, qd0 = jnp.asarray(q0), jnp.asarray(qd0)
    shapes = jax.eval_shape(
        lambda p, a, b: system.observables(t0, a, b, p, field.tau(t0, a, b, tau_const)),
        params,
        q0,
        qd0,
    )
    if requested is True:  # all but those reported as their maximum at the end
        names = tuple(n for n in shapes if n not in system.final_maxima)
    elif isinstance(requested, str):
        names = (requested,)
    else:
        try:
            names = tuple(requested)
        except TypeError:
            names = (requested,)
        if not all(isinstance(n, str) for n in names):
            raise ArgumentTypeError(
                f"observables must be True, a name or a sequence of names (str); got {requested!r}"
            )
    if names and callable(keep):
        raise ConfigurationError(
            f"observables={requested!r} with a keep= reduction: the Solution that reduce "
            "receives carries the observables already (e.g. solution.contact_force); return "
            "them from reduce, or keep 'final', 'trajectory' or times"
        )
    for n in names:
        if n not in shapes:
            close = difflib.get_close_matches(n, list(shapes), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigurationError(
                f"observables: {system.name!r} reports no observable {n!r}{hint}; it reports "
                f"{sorted(shapes)}"
            )
    for n in names:
        if n in system.final_maxima:
            raise ConfigurationError(
                f"observables: {n!r} is reported already, as its largest magnitude at the "
                f"end (the Dataset's {n!r}); keep=reduce returns it along the path"
            )
    named = system.observable_dims()
    out = []
    for n in dict.fromkeys(names):
        ndim = len(shapes[n].shape)
        dims = tuple(named.get(n, ()))
        if len(dims) != ndim:
            dims = tuple(f"{n}_dim_{k}" for k in range(ndim))
        out.append((n, dims))
    return tuple(out)


def observe(setup, field, members, tau_const, ts, t1, out) -> NamedArrays:
    """The observables `setup.observed` of a chunk's solves (`out`, a `LaneOutput`):
    at the saves `ts` (`(M, T, ...)`, `inf` where a member did not reach a save), or,
    with `setup.observe_end`, at the state each solve ended in (`(M, ...)`)."""
    system, names = setup.config.system, setup.observed
    if setup.observe_end:
        (q_end, qd_end), t_end = out.y_end, jnp.minimum(out.t_end, t1)
        at = jax.vmap(
            lambda t, a, b, p: system.observables(t, a, b, p, field.tau(t, a, b, tau_const))
        )(t_end, q_end, qd_end, members)
    else:
        q, qd = out.ys

        def one(p, a, b):
            reached = jnp.all(jnp.isfinite(a), axis=1)
            member_ts = jnp.where(reached, ts, jnp.inf)
            return observables(system, field, p, tau_const, member_ts, a, b)

        at = jax.vmap(one)(members, q, qd)
    return NamedArrays(names, tuple(at[n] for n in names))
