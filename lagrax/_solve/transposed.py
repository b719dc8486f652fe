"""Reverse mode through a solve by forward sensitivities, for few differentiated inputs.

`jax.grad` through `simulate` normally runs the lean loop in reverse: the loop is
checkpointed, and the backward pass recomputes and transposes every step. For the small
systems of mechanics that machinery costs several solves. When only `k` input scalars are
differentiated (`q0` and `qd0`, or a handful of parameters) and `k` is small, the whole
Jacobian `J = ∂(outputs)/∂(inputs)` is cheaper: one forward solve carrying `k` tangents
(forward sensitivities, the loop run as a plain `lax.while_loop`), after which the
vector–Jacobian product of `jax.grad` is the contraction `J^T ȳ`. This is the classical
choice for few parameters (CVODES' forward sensitivity analysis), and it is exact: the
derivative of the discrete solve that was taken.

`solve` here is a `jax.custom_vjp` around `simulate.solve` whose forward rule computes the
primal and the `k` tangents together (JAX's `jacfwd` construction: `vmap` of `jvp` over a
basis of the perturbed inputs) and keeps the output tangents; its backward rule contracts
them with the cotangent. `symbolic_zeros=True` tells the forward rule which inputs are
perturbed, so only those are seeded.

`simulate` takes this route when it is traced by reverse mode alone, lagrax picks the
adjoint (`adjoint=None`), the perturbed scalars it can see number at most
`max_tangents(n)`, and no perturbed value hides in a closure. (A `tau` function's
differentiated closed-over values are hoisted into its fields first, so they count
among the scalars it sees; what else a closure hides takes the checkpointed loop, whose
closure conversion handles it.)
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

# Per differentiated scalar, a forward tangent costs a fraction of a solve (it shares the
# step-size decisions, the factorizations and the loop); the checkpointed reverse pass
# costs about three to ten solves whatever their number. Forward sensitivities win up to
# a few dozen scalars for small systems (measured in benchmarks/bench_derivatives.py).
MIN_TANGENTS = 16


def max_tangents(n_state: int) -> int:
    """The most perturbed input scalars a solve of `n_state` state variables (`2n`)
    takes by forward sensitivities: `max(16, 4n)`, the state and as many parameters."""
    return max(MIN_TANGENTS, 2 * n_state)


def _is_primal(x) -> bool:
    return isinstance(x, jax.custom_derivatives.CustomVJPPrimal)


def _split(dyn):
    """`(values, perturbed)` of the forward rule's arguments (`CustomVJPPrimal`s)."""
    values = jtu.tree_map(lambda p: p.value, dyn, is_leaf=_is_primal)
    perturbed = jtu.tree_map(lambda p: bool(p.perturbed), dyn, is_leaf=_is_primal)
    return values, perturbed


def _seeded(values, perturbed):
    """`(leaves, where, sizes)`: the flat leaves of `values`, the indices of the
    perturbed floating-point ones, and their sizes."""
    leaves = jtu.tree_leaves(values)
    flags = jtu.tree_leaves(perturbed)
    where = [
        i
        for i, (x, p) in enumerate(zip(leaves, flags, strict=True))
        if p and jnp.issubdtype(jnp.result_type(x), jnp.inexact)
    ]
    sizes = [int(np.prod(jnp.shape(leaves[i]))) for i in where]
    return leaves, where, sizes


@functools.partial(jax.custom_vjp, nondiff_argnums=(0, 1))
def _call(fn, static, dyn):
    return fn(eqx.combine(dyn, static))


def _call_fwd(fn, static, dyn):
    values, perturbed = _split(dyn)
    leaves, treedef = jtu.tree_flatten(values)
    flags = jtu.tree_leaves(perturbed)
    where = [i for i, (x, p) in enumerate(zip(leaves, flags, strict=True)) if p and _is_float(x)]
    # the perturbed leaves' shapes, as zeros in dyn's structure (None elsewhere)
    marks = jtu.tree_unflatten(
        treedef, [jnp.zeros_like(x) if i in where else None for i, x in enumerate(leaves)]
    )
    if not where:
        return fn(eqx.combine(values, static)), (None, marks)

    def of_seeded(*seeded):
        full = list(leaves)
        for i, x in zip(where, seeded, strict=True):
            full[i] = x
        return fn(eqx.combine(jtu.tree_unflatten(treedef, full), static))

    sizes = [leaves[i].size for i in where]
    k = sum(sizes)
    seeds, start = [], 0
    for i, size in zip(where, sizes, strict=True):
        x = leaves[i]
        eye = jnp.eye(k, size, -start, dtype=x.dtype)  # rows start…start+size: the identity
        seeds.append(eye.reshape((k, *x.shape)))
        start += size

    def one(*tangents):
        return jax.jvp(of_seeded, [leaves[i] for i in where], list(tangents))

    out, tangents = jax.vmap(one, out_axes=(None, 0))(*seeds)
    kept = jtu.tree_map(lambda t: t if _is_float(t) else None, tangents)
    return out, (kept, marks)


def _is_float(x) -> bool:
    return eqx.is_array(x) and jnp.issubdtype(x.dtype, jnp.inexact)


def _is_zero(x) -> bool:
    return x is None or isinstance(x, jax.custom_derivatives.SymbolicZero)


def _call_bwd(fn, static, residuals, cotangent):
    """`J^T ȳ`, split over the perturbed leaves (`None`, a zero, for the others)."""
    tangents, marks = residuals
    if tangents is None:
        return (jtu.tree_map(lambda m: None, marks),)
    tans = jtu.tree_leaves(tangents, is_leaf=lambda x: x is None)
    cots = jtu.tree_leaves(cotangent, is_leaf=_is_zero)
    mark_leaves, mark_def = jtu.tree_flatten(marks, is_leaf=lambda x: x is None)
    k = sum(m.size for m in mark_leaves if m is not None)
    total = jnp.zeros(k, tans[0].dtype if tans and tans[0] is not None else float)
    for t, c in zip(tans, cots, strict=True):
        if t is None or _is_zero(c) or not _is_float(c):
            continue
        total = total + jnp.tensordot(t, c.astype(t.dtype), axes=c.ndim)
    out, start = [], 0
    for m in mark_leaves:
        if m is None:
            out.append(None)
            continue
        part = total[start : start + m.size]
        out.append(part.reshape(m.shape).astype(m.dtype))
        start += m.size
    return (jtu.tree_unflatten(mark_def, out),)


_call.defvjp(_call_fwd, _call_bwd, symbolic_zeros=True)


def call(fn, args):
    """`fn(args)`, differentiated in reverse mode by forward sensitivities."""
    dyn, static = eqx.partition(args, eqx.is_array)
    out = _call(fn, static, dyn)
    return jtu.tree_map(_constant, out)


def _constant(x):
    """An integer or boolean output (a result code, a count) as a constant of reverse
    mode: a custom rule's outputs all carry tangents, and a later check on them (an
    `error_if` under `jit`) must not be differentiated. Through the floating-point type,
    whose `stop_gradient` has a zero tangent; exact for these small integers."""
    if not eqx.is_array(x) or _is_float(x):
        return x
    wide = jnp.float64 if jax.config.read("jax_enable_x64") else jnp.float32
    return jax.lax.stop_gradient(x.astype(wide)).astype(x.dtype)
