"""Cache blocking of large batches: a function vmapped over many states runs in blocks.

A `jax.vmap` over `B` states runs every operation of the function over all `B` at once:
each intermediate is an array of `B` values. For a multibody recursion the intermediates
of one state are a few hundred scalars, so at `B = 4096` the arrays of one step no longer
fit the CPU's caches and the evaluation is bound by memory traffic (a humanoid's forward
dynamics: about 5 µs per state in blocks of 64 states, 10 µs over 4,096 at once, on a
2-core CPU).

`blocked(fn, size)` is `fn` with a batching rule (`jax.custom_batching.custom_vmap`):
vmapped over more than `size` states on a CPU, it runs as `jax.lax.map` over blocks of
`size` states, each block vmapped (the last one short). The values are the plain vmap's to
round-off: the same operations per state, perhaps fused differently.

- Only batches larger than a block take the rule: an unbatched call (a solve's vector
  field) and small batches (a sweep's 16 lanes) trace `fn` once, as they always did.
- On a GPU nothing is blocked: its threads want the whole batch.
- `fn` is never differentiated through the rule (JAX cannot transpose it): the blocked
  function's derivative is JAX's derivative of `fn` itself (a custom JVP), so `grad`,
  `jacfwd` and higher orders see `fn`. The functions blocked here are evaluations at
  primal values (the accelerations, the Jacobians their custom JVP applies, the
  derivatives call), whose cost is what blocking saves.
- A function closing over a vmapped value (a user's energy capturing a batched
  parameter) cannot take the rule (`custom_vmap` refuses batched closures): it runs as
  the plain vmap.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
from jax.custom_batching import custom_vmap

try:  # the batch tracer's type and its mapped axis are not public API
    from jax._src.interpreters.batching import BatchTracer
except ImportError:  # pragma: no cover - another JAX: no blocking, plain vmap
    BatchTracer = ()

BLOCK = 64
"""States per block (CPU). Forward dynamics per state, one vmapped call over 4,096
states, unblocked / blocks of 16, 32, 64, 128, 256 (2-core CPU): G1 humanoid 9.8 / 6.5,
6.8, 4.9–5.6, 6.4–7.0, 6.8 µs; the URDF arm `arm7` 1.55 / 0.58 µs at 64."""


def _batch_size(x: Any) -> int:
    """The size of the vmap axis of `x` at the innermost batching level, or 0."""
    dim = getattr(x, "batch_dim", None)
    if not (isinstance(x, BatchTracer) and isinstance(dim, int)):
        return 0
    try:
        return int(x.val.shape[dim])
    except (AttributeError, IndexError, TypeError):  # another JAX's tracer: not blocked
        return 0


def blocked(fn: Callable[..., Any], size: int | None = BLOCK) -> Callable[..., Any]:
    """`fn(*args)`, evaluated in blocks of `size` states when vmapped over more (`size`
    `None`: `fn` itself, never blocked).

    `args` may hold non-array leaves (modules with callables, flags): they are held
    fixed. Values closed over by `fn` that are themselves batched (a user function
    closing over a vmapped value) cannot be blocked: then `fn` runs as a plain vmap.
    """

    if size is None:
        return fn

    def wrapper(*args: Any) -> Any:
        dynamic, static = eqx.partition(args, eqx.is_array)
        batch = max((_batch_size(x) for x in jax.tree_util.tree_leaves(dynamic)), default=0)
        if batch <= size or jax.default_backend() != "cpu":
            return fn(*args)

        def call(dyn: Any) -> Any:
            return fn(*eqx.combine(dyn, static))

        @custom_vmap
        def run(dyn: Any) -> Any:
            return call(dyn)

        @run.def_vmap
        def _rule(axis_size: int, in_batched: Any, dyn: Any) -> Any:
            flags = jax.tree_util.tree_leaves(in_batched)
            leaves, tree = jax.tree_util.tree_flatten(dyn)
            mapped = [v for v, b in zip(leaves, flags, strict=True) if b]

            def one(values: Any) -> Any:
                it = iter(values)
                full = [next(it) if b else v for v, b in zip(leaves, flags, strict=True)]
                return call(jax.tree_util.tree_unflatten(tree, full))

            out = jax.lax.map(one, mapped, batch_size=size)
            return out, jax.tree_util.tree_map(lambda _: True, out)

        @jax.custom_jvp
        def primal(dyn: Any) -> Any:
            return run(dyn)

        @primal.defjvp
        def _jvp(primals: Any, tangents: Any) -> Any:
            return jax.jvp(call, primals, tangents)

        try:
            return primal(dynamic)
        except AssertionError:  # batched values closed over (JAX's custom_vmap refuses them)
            return fn(*args)

    return wrapper
