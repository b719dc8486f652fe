"""Floating bases from the loaders: the root link of a URDF with the links fixed to it
merged into one base body, and a tree put on a base whose inertia a loader merged."""

import math
import warnings
from typing import Any

import jax.numpy as jnp
import numpy as np

from ..._core.errors import URDFError, URDFWarning
from ..articulated.trees import Tree
from ..common import steiner
from ..inertia import check_inertia
from .system import FloatingTree


def base_from_urdf(
    tree: Tree, params: dict, place: dict, order: list, links: dict, root: str, inertial: Any
) -> tuple[FloatingTree, dict]:
    """`from_urdf(..., floating_base=True)`: the base is the root link with every link
    fixed to it (merged by the parallel-axis theorem, as the tree's bodies are)."""
    mass, moment, inertia_o = 0.0, np.zeros(3), np.zeros((3, 3))
    for link in order:
        body, rot, pos = place[link]
        if body >= 0:
            continue
        try:
            part = inertial(links[link])
        except URDFError as err:  # checked on the merged base below
            part = inertial(links[link], check=False)
            warnings.warn(
                f"link {link!r} (fixed to the floating base {root!r}): {err}; merged into "
                "the base as given (the base's merged inertia is checked)",
                URDFWarning,
                stacklevel=3,
            )
        if part is None:
            continue
        c = pos + rot @ part.com
        mass += part.mass
        moment = moment + part.mass * c
        inertia_o = inertia_o + rot @ part.inertia @ rot.T
        inertia_o = inertia_o + steiner(part.mass, c)
    if not mass > 0 or not math.isfinite(mass):
        raise URDFError(
            f"root link {root!r} (with the links fixed to it) has mass {mass:g}: a floating "
            "base needs a positive mass; give it an <inertial>"
        )
    com = moment / mass
    inertia = inertia_o - steiner(mass, com)
    inertia = 0.5 * (inertia + inertia.T)
    return on_base(tree, params, (mass, com, inertia), root, f"link {root!r}")


def on_base(
    tree: Tree, params: dict, base: tuple, name: str, what: str
) -> tuple[FloatingTree, dict]:
    """The [`FloatingTree`][lagrax.chains.FloatingTree] of `tree` on a base named `name`
    whose `(mass, com, inertia)` (the inertia about the centre of mass, base frame) a
    loader merged, and `params` plus `base_m`, `base_com`, `base_inertia` (the inertia
    checked, named `what` in its error)."""
    mass, com, inertia = base
    dtype = params["m"].dtype
    out = dict(params)
    out["base_m"] = jnp.asarray(mass, dtype)
    out["base_com"] = jnp.asarray(com, dtype)
    out["base_inertia"] = check_inertia(
        jnp.asarray(inertia, dtype)[None], name=f"{what} inertia", semidefinite=True
    )[0]
    return FloatingTree(tree, base_name=name), out
