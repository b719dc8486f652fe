"""Values that user functions close over: the tracers a system's energies or a `tau`
function capture when a system is built inside a transformed function, and the autodiff
modes that traced them.

A system built inside `jax.jit` or `jax.vmap` of a user's function may close over a traced
value (`V = ½ k q·q` with `k` the function's argument): its calls are then traced even
where the arrays passed are concrete. Under `jax.grad` or `jax.jvp` such a closure hides a
derivative from any custom rule (a rule sees only its arguments): callers then hoist the
values into the function's fields (`hoisted`: `simulate` does for a `tau` function), take
plain automatic differentiation, or refuse with a message that says to pass the value
through `params`.
"""

import contextlib
import dataclasses
import functools
import types
import weakref
from collections.abc import Callable

import equinox as eqx
import jax

try:  # JAX's tracer types of jax.jvp and of linearize (jax.grad): private, so looked up softly
    from jax._src.interpreters import ad as _ad

    _JVP_TRACER = getattr(_ad, "JVPTracer", ())
    _LINEARIZE_TRACER = getattr(_ad, "LinearizeTracer", ())
except ImportError:  # pragma: no cover - a JAX that moved them: modes are not seen
    _JVP_TRACER = _LINEARIZE_TRACER = ()


def modes(tracer) -> set[str]:
    """The autodiff modes among the transformations that traced `tracer` (each JAX
    tracer holds the one it wraps): `"forward"` for `jax.jvp` / `jax.jacfwd`,
    `"reverse"` for `jax.grad` / `jax.vjp` / `jax.jacrev` (JAX linearizes, then
    transposes)."""
    found = set()
    while isinstance(tracer, jax.core.Tracer):
        if isinstance(tracer, _JVP_TRACER):
            found.add("forward")
        elif isinstance(tracer, _LINEARIZE_TRACER):
            found.add("reverse")
        inner = None
        for attr in ("primal", "val"):  # JVP and linearize tracers; batch tracers
            value = getattr(tracer, attr, None)
            if isinstance(value, jax.core.Tracer):
                inner = value
                break
        tracer = inner
    return found


def _functions(value, depth: int = 2):
    """The functions among `value`: itself, or a system's fields (shallow, so that a
    tree's many arrays are not walked on every call), and those of a system it holds (a
    constrained system's unconstrained one), `depth` levels of systems down."""
    if isinstance(value, _FUNCTIONS):
        yield value
    elif depth > 0 and dataclasses.is_dataclass(value) and not isinstance(value, type):
        for field in vars(value).values():
            if isinstance(field, _FUNCTIONS) or dataclasses.is_dataclass(field):
                yield from _functions(field, depth - 1)


def _hidden(values):
    """The tracers that functions among `values` close over, lazily (see `_functions`).
    A function found clean is remembered (`_CLEAN`)."""
    seen: set[int] = set()
    for value in values:
        for fn in _functions(value):
            if fn not in _CLEAN:
                clean = True
                for leaf in closure_tracers(fn, 4, seen):
                    clean = False
                    yield leaf
                if clean:
                    with contextlib.suppress(TypeError):  # (not weakly referenceable)
                        _CLEAN.add(fn)


def hidden_tracers(*values) -> list:
    """The traced values that functions among `values` (a `tau` function, a system's
    energies) close over."""
    return list(_hidden(values))


def closes_over_tracers(*values) -> bool:
    """Whether a function among `values` (a `tau` function, a system's energies) closes
    over a traced value: then a call is traced even where its arrays are concrete (a
    system built inside a function that `jax.jit` or `jax.vmap` transforms)."""
    return next(_hidden(values), None) is not None


_FUNCTIONS = (types.FunctionType, types.MethodType, functools.partial)
# Functions found to close over no tracer (the usual case: defined outside any transform);
# eager `simulate` calls reuse them, so each is walked once.
_CLEAN: "weakref.WeakSet" = weakref.WeakSet()


def closure_tracers(fn, depth: int, seen: set[int]):
    """The tracers a function closes over (its cells, a `functools.partial`'s arguments,
    a bound method's owner), `depth` levels of functions down."""
    if depth == 0 or id(fn) in seen:
        return
    seen.add(id(fn))
    if isinstance(fn, functools.partial):
        inner = [fn.func, fn.args, fn.keywords]
    elif isinstance(fn, types.MethodType):
        inner = [fn.__func__, fn.__self__]
    elif isinstance(fn, types.FunctionType):
        inner = [c.cell_contents for c in (fn.__closure__ or ()) if _filled(c)]
    else:
        inner = []
    for value in inner:
        for leaf in jax.tree_util.tree_leaves(value):
            if isinstance(leaf, jax.core.Tracer):
                yield leaf
            elif callable(leaf):
                yield from closure_tracers(leaf, depth - 1, seen)


def _filled(cell) -> bool:
    try:
        cell.cell_contents  # noqa: B018
    except ValueError:  # an empty cell
        return False
    return True


def differentiated(*values) -> bool:
    """Whether any leaf of `values` is traced by automatic differentiation (either mode)."""
    return any(modes(leaf) for leaf in jax.tree_util.tree_leaves(values))


def differentiated_closure(*values) -> bool:
    """Whether a function among `values` closes over a value that automatic
    differentiation traces (a derivative that a custom rule would not see)."""
    return any(modes(leaf) for leaf in _hidden(values))


class Hoisted(eqx.Module):
    """A function whose closed-over differentiated values are its fields: `fn(*args,
    *consts)` (from `jax.closure_convert`), so that a custom rule sees their tangents as
    it sees any array's (`hoisted`)."""

    fn: Callable = eqx.field(static=True)
    consts: tuple

    def __call__(self, *args):
        return self.fn(*args, *self.consts)


def hoisted(fn, *example_args):
    """`fn` with the values that automatic differentiation traces, among those it closes
    over (a controller's gains, say), hoisted into its fields (a `Hoisted`), traced at
    `example_args`' shapes and dtypes; `fn` itself where it closes over none."""
    if not differentiated_closure(fn):
        return fn
    converted, consts = jax.closure_convert(fn, *example_args)
    return Hoisted(converted, tuple(consts))
