"""`simulate`'s compiled call: one program per configuration, reached in about a
microsecond of Python.

A call of `simulate` on concrete inputs runs one compiled *program*: a function
`program(config, fields)` of the solve's configuration (static: the model and the method,
`simulate.SolveConfig`) and the fields of its inputs (arrays: `simulate.SolveInputs`
as a tuple). Three things keep the per-call overhead near 0.2 ms, and this module holds
all three:

- `run_once`: the whole program sits inside a `lax.while_loop` that runs once, so that
  XLA:CPU compiles it into one kernel (see `xla_flags`) instead of running dozens of
  small ones around the solver loop (~0.1 ms a call).
- `compiled`: a `jax.jit` of the program per configuration, taking the fields as a
  tuple. `equinox.filter_jit` sorts arrays from static values on every call, which for
  `simulate`'s arguments costs about as much as a short solve; with the configuration
  fixed and every input an array, a call is `jax.jit`'s C++ fast path. It compiles with
  the options of a one-trajectory program (`xla_flags.one_shot_options`: on the CPU,
  the loop emitter, which compiles these programs faster for the same speed).
- `configured`: the front cache, keyed on the identity of the configuration's parts.
  Hashing and comparing a `SolveConfig` walks the whole system (~60 µs each for a
  7-link chain, and building one as much again); a repeated call with the same objects
  skips all three.

`call` runs the program through them, and falls back to `equinox.filter_jit` where
they cannot serve (an unhashable configuration, non-array inputs).
"""

import collections
import functools
import threading
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.one_shot import one_shot
from .._core.xla_flags import one_shot_options

Program = Callable[[Any, tuple], Any]  # program(config, fields) -> a pytree of outputs


def run_once(program: Program, config: Any, fields: tuple) -> Any:
    """`program(config, fields)`, inside a `lax.while_loop` that runs once.

    Only for concrete inputs (a while loop is not reverse-differentiable), where it makes
    XLA:CPU compile the whole program into one kernel. The program is traced under
    `one_shot`: it runs one trajectory once, so large trees take the form of
    their recursions that compiles fastest.
    """
    with one_shot():
        shapes = eqx.filter_eval_shape(program, config, fields)  # traced once; reused
    init = (
        jnp.asarray(False),
        jax.tree_util.tree_map(
            lambda x: jnp.zeros(x.shape, x.dtype) if isinstance(x, jax.ShapeDtypeStruct) else x,
            shapes,
        ),
    )

    def once(_):
        with one_shot():
            return program(config, fields)

    _, out = jax.lax.while_loop(lambda c: ~c[0], lambda c: (jnp.asarray(True), once(None)), init)
    return out


_run_once = eqx.filter_jit(run_once)  # where the jax.jit of `compiled` cannot serve


@functools.lru_cache(maxsize=64)
def compiled(program: Program, config: Any):
    """A `jax.jit` of `run_once(program, config, fields)` taking the fields as a tuple,
    and the static part of its outputs: `(fn, (out_static, tracing))`.

    **Raises:** `TypeError` when `config` is not hashable (see `compiled_or_none`).
    """
    # The output's static part (its treedef and non-array leaves) depends on the inputs'
    # structure too (a constant `tau` adds the work, `ts` sets the saves): it is kept per
    # input signature, the key under which `jax.jit` itself caches a trace.
    out_static: dict = {}
    tracing = threading.local()  # .signature: that of the call being traced (this thread's)

    def run(fields):
        leaves, treedef = jax.tree_util.tree_flatten(run_once(program, config, fields))
        arrays = [i for i, x in enumerate(leaves) if eqx.is_array(x)]
        out_static[tracing.signature] = (treedef, leaves, arrays)
        return [leaves[i] for i in arrays]

    return jax.jit(run, compiler_options=one_shot_options()), (out_static, tracing)


def compiled_or_none(program: Program, config: Any):
    """`compiled(program, config)`, or `None` for an unhashable configuration."""
    try:
        return compiled(program, config)
    except TypeError:
        return None


# The front cache: the program and the configuration's parts by identity -> (parts,
# config, compiled or None). The entry holds the parts themselves, so an `id` cannot be
# reused while it lives; a miss falls through to `compiled`, whose cache compares by
# value (equal systems share one compiled program).
_FRONT: "collections.OrderedDict[tuple, tuple]" = collections.OrderedDict()
_FRONT_SIZE = 64


def configured(program: Program, make: Callable, parts: tuple, n_save: int, max_steps: int):
    """`(config, compiled)` for `config = make(*parts, n_save, max_steps, None)`, where
    `compiled` is `compiled(program, config)`, or `None` when the configuration is not
    hashable (a controller or saveat holding arrays)."""
    key = (program, *map(id, parts), n_save, max_steps)
    hit = _FRONT.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], parts, strict=True)):
        return hit[1], hit[2]
    config = make(*parts, n_save, max_steps, None)
    fn = compiled_or_none(program, config)
    _FRONT[key] = (parts, config, fn)
    if len(_FRONT) > _FRONT_SIZE:
        _FRONT.popitem(last=False)
    return config, fn


def call(program: Program, config: Any, fields: tuple, fn=None):
    """`run_once(program, config, fields)`, through the cached `jax.jit` `fn` (from
    `compiled`) when given and every input is an array."""
    flat, structure = jax.tree_util.tree_flatten(fields)
    if fn is None or not all(eqx.is_array(x) for x in flat):
        # no jit of its own (unhashable settings), or non-array leaves (e.g. strings in
        # params): equinox sorts them out
        return _run_once(program, config, fields)
    jitted, (out_static, tracing) = fn
    signature = (structure, *((x.shape, x.dtype, getattr(x, "weak_type", False)) for x in flat))
    tracing.signature = signature
    values = jitted(fields)
    treedef, leaves, arrays = out_static[signature]
    leaves = list(leaves)  # the static leaves, with the arrays put back in their places
    for i, value in zip(arrays, values, strict=True):
        leaves[i] = value
    return jax.tree_util.tree_unflatten(treedef, leaves)
