"""Compiled programs that live as long as the model they were compiled for.

`equinox.filter_jit(body)` at module level keeps every program it compiles, and the
model's functions (its static part) in the key, for as long as the process runs: a user
who explores robots in one session pays for each one they ever touched (about 120 MB a
robot, nearly all compiled code), and no `del` gives it back.

`program(model, body)` is instead a `filter_jit` of `body` owned by the model: a new
function object per model, so that JAX's and equinox's caches, which hold a jitted
function's programs weakly by that function, drop them once the model is collected. A
repeated call with the same live model hits the same compiled program; a call with a
new model (even an equal one) compiles its own. At most `MAX_MODELS` models keep
programs here (the oldest is forgotten first), so a model that its own functions keep
alive through a cache key cannot pile up either.
"""

import collections
import functools
import weakref
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .checks import traced

MAX_MODELS = 32

# id(model) -> (weak reference to the model, {(body, options): its filter_jit})
_OWNED: "collections.OrderedDict[int, tuple[weakref.ref, dict]]" = collections.OrderedDict()


def _forget(key: int, ref: weakref.ref) -> None:
    """The model behind `ref` was collected: drop its programs (not a newer model's that
    reuses the id)."""
    entry = _OWNED.get(key)
    if entry is not None and entry[0] is ref:
        del _OWNED[key]


class _Static(eqx.Module):
    """The non-array part of a program's outputs, carried in the output's structure."""

    value: Any = eqx.field(static=True)


def _compile(body: Callable, jit_options: dict) -> Callable:
    """`body` compiled as `equinox.filter_jit` does (arrays among the arguments traced,
    the rest: functions, ints, strings, static), with a `jax.jit` of its own per static
    part, closing over it. JAX keeps a jitted function's static arguments in caches that
    outlive it (`filter_jit`'s hold its own function, so it is never freed); a closure is
    not in their keys, so they drop its programs once `call` is collected."""
    jitted: dict = {}  # static part -> its jax.jit

    def jit_for(static: tuple) -> Callable:
        leaves, treedef = static

        def run(dynamic: list) -> Any:
            values = [x if s is _ARRAY else s for x, s in zip(dynamic, leaves, strict=True)]
            out = body(*jax.tree_util.tree_unflatten(treedef, values))
            arrays, others = eqx.partition(out, eqx.is_array)
            return arrays, _Static(others)

        return jax.jit(run, **jit_options)

    @functools.wraps(body)
    def call(*args: Any) -> Any:
        leaves, treedef = jax.tree_util.tree_flatten(args)
        arrays = [eqx.is_array(x) for x in leaves]
        dynamic = [x if a else None for x, a in zip(leaves, arrays, strict=True)]
        static = (tuple(_ARRAY if a else x for x, a in zip(leaves, arrays, strict=True)), treedef)
        try:
            fn = jitted.get(static)
        except TypeError:  # an unhashable non-array argument (a callable object): as is
            return body(*args)
        if fn is None:
            fn = jitted[static] = jit_for(static)
        out, others = fn(dynamic)
        return eqx.combine(out, others.value)

    return call


class _ArrayMarker:
    """Where an array goes among the static leaves."""


_ARRAY = _ArrayMarker()


def program(model: Any, body: Callable, **jit_options: Any) -> Callable:
    """`body` compiled as by `equinox.filter_jit(body, **jit_options)`, one per live
    `model`, collected with it.

    **Arguments:** `model`, the object whose lifetime the program follows (a system);
    `body`, the function to compile (positional arguments only); `jit_options`, passed
    to `jax.jit` (their `repr` tells them apart).

    **Returns:** the compiled function; the same object for the same `model`, `body` and
    options while the model lives.
    """
    key = id(model)
    entry = _OWNED.get(key)
    if entry is None or entry[0]() is not model:
        ref = weakref.ref(model, functools.partial(_forget, key))
        entry = _OWNED[key] = (ref, {})
        if len(_OWNED) > MAX_MODELS:
            _OWNED.popitem(last=False)
    else:
        _OWNED.move_to_end(key)
    options = repr(sorted(jit_options.items()))
    fn = entry[1].get((body, options))
    if fn is None:
        fn = entry[1][(body, options)] = _compile(body, jit_options)
    return fn


def clear() -> None:
    """Forget every model's programs (they are freed once nothing else holds them)."""
    _OWNED.clear()


def call(model: Any, body: Callable, *args: Any) -> Any:
    """`body(*args)`: compiled as one program of `model` (`program`) where nothing is
    traced, else `body` itself (inside a transformation, or a model whose functions close
    over traced values, which a compiled program cannot hold as constants).

    Python floats among `args` (a time `t`, a parameter) are passed as weakly typed
    scalars, so that a new value does not compile a new program (`filter_jit` keeps them
    static) and a float32 state stays float32.
    """
    if traced(model, *args):
        return body(*args)
    args = jax.tree_util.tree_map(lambda x: jnp.asarray(x) if isinstance(x, float) else x, args)
    return program(model, body)(*args)
