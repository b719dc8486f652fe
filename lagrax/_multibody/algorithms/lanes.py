"""Lanes: how the recursions run over a tree with `lax.scan` (one scan per phase of
bodies at the same depth, every scalar a `(W,)` array over the bodies of a lane), and the
per-link scalars they read (NumPy constants as Python floats, so structural zeros stay
zeros)."""

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np


def leaf_scalars(x: Any) -> Any:
    """A per-link leaf as scalars: NumPy constants as Python floats (structural zeros
    stay zeros), JAX arrays as nested tuples of JAX scalars."""
    if isinstance(x, float):
        return x
    if isinstance(x, (np.ndarray, np.generic)):
        return float(x) if x.ndim == 0 else tuple(leaf_scalars(v) for v in x)
    if x.ndim == 0:
        return x
    return tuple(leaf_scalars(x[i]) for i in range(x.shape[0]))


def scalars(x: Any) -> Any:
    """Every leaf of a per-link pytree as scalars (see `leaf_scalars`)."""
    return jax.tree_util.tree_map(leaf_scalars, x)


def as_arrays(x: Any, dtype: Any) -> Any:
    return jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype), x)


MAX_PHASES = 5
"""The most phases (scans per pass) of a tree's [`Lanes`][]: XLA compiles one loop per
phase and pass (a floating base's forward dynamics: about 1–2 s more per phase, without
the persistent cache), so a tree of more phases (a robot with hands, TIAGo, PR2) runs
its passes as one scan over its bodies instead, with every body's carry in a buffer read
and written by parent index (several times slower per state, compiled about as fast as
one phase). Quadrupeds and arms have one phase, G1 three, TALOS four, dm_control's
humanoid_CMU and dog five (at 5 rather than 4: 93 → 11 µs and 136 → 15 µs a state, the
first compile 3.5 → 6.9 s and 3.9 → 6.5 s; `bench_scale.py --sections 5`)."""


class Lanes:
    """A tree's bodies laid out for scans vectorized over its branches.

    The tree is cut into *segments*: a body continues its parent's segment where it is
    the parent's only child, so a segment ends at a leaf or at a branching body. Segments
    are grouped by their number of ancestor segments (a humanoid: its legs and torso, then
    its arms and head), and a group's segments are its *lanes*, longest first. A group is
    run as *phases*, one `lax.scan` each: phase `k` runs depths `[l_{k−1}, l_k)` (`l_k`
    the lanes' distinct lengths) over the lanes still running, a prefix of them, so every
    step does the work of all its lanes at once and no lane is padded.

    A pass then costs one scan step per depth of each group instead of one per body, and
    every carry is handed from step to step: no buffer of all the bodies' carries, read
    and written by parent index. A segment of group `g + 1` hangs from the last body of a
    segment of group `g` (a branching body ends its segment), so between phases and
    groups only lanes' final carries are passed on (outward) or summed into their parent
    lanes (inward).

    **Arguments:** `parents`, each body's parent (`−1`: the base), with `parents[i] < i`.
    """

    def __init__(self, parents: tuple[int, ...]):
        n = len(parents)
        children = [0] * n
        for p in parents:
            if p >= 0:
                children[p] += 1
        segment_of = [0] * n
        segments: list[list[int]] = []
        level: list[int] = []
        for i, p in enumerate(parents):
            if p >= 0 and children[p] == 1:
                segment_of[i] = segment_of[p]
                segments[segment_of[i]].append(i)
                continue
            segment_of[i] = len(segments)
            segments.append([i])
            level.append(0 if p < 0 else level[segment_of[p]] + 1)
        groups = []
        for g in range(max(level) + 1):
            group = [k for k in range(len(segments)) if level[k] == g]
            groups.append(sorted(group, key=lambda k: -len(segments[k])))
        lane_of = {k: w for group in groups for w, k in enumerate(group)}
        # per group: its width and the lane (in group g − 1) each lane hangs from
        self.widths = tuple(len(group) for group in groups)
        self.parent_lane = [None] + [
            np.array([lane_of[segment_of[parents[segments[k][0]]]] for k in group])
            for group in groups[1:]
        ]
        # per group, its phases: (group, width, (depth, width) body indices)
        self.phases: list[list[tuple[int, int, np.ndarray]]] = []
        order = np.zeros(n, int)
        offset = 0
        for g, group in enumerate(groups):
            lengths = [len(segments[k]) for k in group]
            phases, begin = [], 0
            for end in sorted(set(lengths)):
                width = sum(length >= end for length in lengths)
                index = np.array([segments[k][begin:end] for k in group[:width]]).T
                order[index] = offset + np.arange(index.size).reshape(index.shape)
                offset += index.size
                phases.append((g, width, index))
                begin = end
            self.phases.append(phases)
        self.order = order  # body i's place in the phases' flattened (depth, lane) grids


def lane_scalars(x: Any) -> Any:
    """A lane-vectorized leaf (`(…, W)`, lanes last) as nested tuples of `(W,)` arrays."""
    if isinstance(x, float) or x.ndim <= 1:
        return x
    return tuple(lane_scalars(x[i]) for i in range(x.shape[0]))


def components(x: Any) -> Any:
    """A phase's input leaf (`(depth, …, W)`): a NumPy constant as nested tuples of
    `(depth, W)` entries, each entry equal over the whole phase as a Python float (a
    structural zero or one the step's scalar algebra skips); other leaves as they are."""
    if not isinstance(x, np.ndarray):
        return x
    if x.ndim == 2:
        return float(x.flat[0]) if np.all(x == x.flat[0]) else x
    return tuple(components(x[:, i]) for i in range(x.shape[1]))


def lane_scan(step: Callable, carry: Any, xs: Any, reverse: bool, dtype: Any):
    """`lax.scan` of `step` over one phase of [`Lanes`][]: every scalar a `(W,)` array.

    Inputs equal over the phase stay Python floats inside the step (not scanned), and
    of the step's outputs only the distinct arrays are stacked: a Python float (a
    structural zero) stays a float in the outputs, and a value the step returns twice
    (a symmetric inertia's mirrored entries) is stored once. Both spare the memory
    traffic of writing and reading back per-body arrays between passes, and the floats
    let the next pass skip work as the unrolled code does."""
    tree_map, flatten = jax.tree_util.tree_map, jax.tree_util.tree_flatten
    leaves, x_def = flatten(tree_map(components, xs))
    fixed = [isinstance(v, float) for v in leaves]
    scanned = [v for v, f in zip(leaves, fixed, strict=True) if not f]
    width = jax.tree_util.tree_leaves(carry)[0].shape[0]
    plan: dict = {}

    def lane_array(v: Any) -> Any:
        return jnp.broadcast_to(jnp.asarray(v, dtype), (width,))

    def body(c, dyn):
        it = iter(dyn)
        x = x_def.unflatten([v if f else next(it) for v, f in zip(leaves, fixed, strict=True)])
        c2, y = step(c, tree_map(lane_scalars, x))
        y_leaves, plan["def"] = flatten(y)
        outs: list = []
        seen: dict = {}
        plan["leaves"] = []
        for v in y_leaves:
            if isinstance(v, float):
                plan["leaves"].append(float(v))
                continue
            if id(v) not in seen:
                seen[id(v)] = len(outs)
                outs.append(lane_array(v))
            plan["leaves"].append(seen[id(v)])
        return tree_map(lane_array, c2), outs

    final, outs = jax.lax.scan(body, tree_map(lane_array, carry), scanned, reverse=reverse)
    y_leaves = [v if isinstance(v, float) else outs[v] for v in plan["leaves"]]
    return final, plan["def"].unflatten(y_leaves)
