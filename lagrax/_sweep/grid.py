"""The batch of a sweep: `Grid`, `grid` and `samples`, and `Members` (the parameters
and initial states of a sweep's members, from a `Grid` or batched parameters)."""

import dataclasses
import math
import re
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._core.checks import is_namedtuple
from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from .options import batch_size

_STATE = re.compile(r"^(q0|qd0)_(\d+)$")
_ELEMENT = re.compile(r"^([A-Za-z_]\w*)\[\s*(-?\d+(?:\s*,\s*-?\d+)*)\s*\]$")


class Grid:
    """A batch of parameter sets and initial states with labels: fixed values plus swept
    ones.

    Made by `grid` (the Cartesian product of named 1-D ranges: one sweep dimension per
    name) or `samples` (named values taken together, member by member: one `"member"`
    dimension, e.g. Monte-Carlo draws). `sweep` labels its results with these names and
    values. A name `q0_i` or `qd0_i` (for an integer `i`) sweeps component `i` of the
    initial coordinates or velocities instead of a parameter (unless the fixed
    parameters have an entry of that name); a name `m[3]` (or `inertia[2, 0, 0]`) sweeps
    one element of an array-valued parameter, the rest of the array staying fixed.

    **Attributes:** `base` (the fixed parameters), `axes` (name → values), `states`
    (the state axes: name → `("q0" | "qd0", i)`), `elements` (the element axes: name →
    `(parameter, index)`), `units` (name → unit string, for the result's coordinate
    attrs), `dims` (the result's sweep dimensions), `shape`, `size` (number of members).
    """

    def __init__(
        self,
        base: Any,
        axes: Mapping[str, np.ndarray],
        product: bool,
        units: Mapping[str, str] | None = None,
    ):
        if base is None:
            base = {}
        if not (isinstance(base, Mapping) or is_namedtuple(base)):
            raise ArgumentTypeError(
                "grid/samples need the fixed parameters as a dict or a NamedTuple (got "
                f"{type(base).__name__}); for other pytrees pass sweep() params whose "
                "leaves all carry a leading batch axis"
            )
        if not axes:
            raise ConfigurationError(
                "name at least one swept parameter, e.g. grid(params, m2=[1, 2])"
            )
        self.base = base
        self.axes = {}
        fixed = base if isinstance(base, Mapping) else base._asdict()
        self.elements = _elements(axes, fixed)
        for name, values in axes.items():
            if name in self.elements:
                leaf: tuple[int, ...] | None = ()  # one element: a scalar per member
            else:
                leaf = np.shape(fixed[name]) if name in fixed else None
            self.axes[name] = _swept(name, values, leaf, product)
        self.states: dict[str, tuple[str, int]] = {}
        for name in self.axes:
            match = _STATE.match(name)
            if match and name not in fixed:
                self.states[name] = (match.group(1), int(match.group(2)))
        self.units: dict[str, str] = {}
        for name, values in axes.items():  # an xarray axis may carry its own units
            unit = getattr(values, "attrs", {}).get("units")
            if unit is not None:
                self.units[name] = str(unit)
        for name, unit in (units or {}).items():
            if name not in self.axes:
                raise ConfigurationError(
                    f"units= names {name!r}, which is not swept (swept: {list(self.axes)})"
                )
            if not isinstance(unit, str):
                raise ArgumentTypeError(
                    f"units= gives {name!r} the unit {unit!r}: a unit is a string, e.g. 'kg'"
                )
            self.units[name] = unit
        self.product = product
        if product:
            self.dims = tuple(self.axes)
            self.shape = tuple(v.size for v in self.axes.values())
        else:
            sizes = {k: v.shape[0] for k, v in self.axes.items()}
            if len(set(sizes.values())) != 1:
                raise ShapeError(f"samples() needs values of one length per name, got {sizes}")
            self.dims = ("member",)
            self.shape = (next(iter(sizes.values())),)
        self.size = math.prod(self.shape)

    def __repr__(self) -> str:
        kind = "grid" if self.product else "samples"
        return f"Grid({kind}, dims={self.dims}, shape={self.shape}, swept={list(self.axes)})"

    def columns(self, start: int = 0, stop: int | None = None) -> dict[str, np.ndarray]:
        """The swept values of members `start:stop` (C order over the grid)."""
        stop = self.size if stop is None else stop
        if not self.product:
            return {k: v[start:stop] for k, v in self.axes.items()}
        idx = np.unravel_index(np.arange(start, stop), self.shape)
        return {k: v[i] for (k, v), i in zip(self.axes.items(), idx, strict=True)}

    def params(self, start: int = 0, stop: int | None = None) -> Any:
        """Batched parameters of members `start:stop`: every leaf has a leading axis."""
        stop = self.size if stop is None else stop
        cols = {k: v for k, v in self.columns(start, stop).items() if k not in self.states}
        n = stop - start
        fixed = dict(self.base) if isinstance(self.base, Mapping) else self.base._asdict()
        out = {}
        for k, v in fixed.items():
            if k not in cols:
                v = jnp.asarray(v)
                out[k] = jnp.broadcast_to(v, (n,) + v.shape)
        for k, v in cols.items():
            if k in self.elements:
                leaf, index = self.elements[k]
                x = out[leaf]
                out[leaf] = x.at[(slice(None), *index)].set(jnp.asarray(v, x.dtype))
            else:
                out[k] = jnp.asarray(v)
        cols = {k: v for k, v in cols.items() if k not in self.elements}
        if isinstance(self.base, Mapping):
            return out
        unknown = set(cols) - set(fixed)
        if unknown:
            raise ConfigurationError(
                f"{sorted(unknown)} are not fields of {type(self.base).__name__}"
            )
        return type(self.base)(**out)

    def initial_states(self, q0: np.ndarray, qd0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every member's initial state `(members, n)`: `q0`, `qd0` (already one row per
        member) with the swept components (`q0_i`, `qd0_i` axes) set."""
        if not self.states:
            return q0, qd0
        out = {"q0": np.array(q0), "qd0": np.array(qd0)}
        cols = self.columns()
        for name, (which, i) in self.states.items():
            n = out[which].shape[-1]  # q and q̇ differ in size on a floating base
            if i >= n:
                raise ShapeError(
                    f"the sweep axis {name!r} sets {which}[{i}], but the system's state has "
                    f"{n} coordinates ({which}_0 … {which}_{n - 1})"
                )
            out[which][:, i] = cols[name]
        return out["q0"], out["qd0"]


def _elements(axes: Mapping[str, Any], fixed: Mapping[str, Any]) -> dict:
    """The swept names that are one element of an array-valued parameter, `"m[3]"` or
    `"inertia[2, 0, 0]"`: name → `(parameter, index)` (the index non-negative, of one
    entry per axis of the parameter). A name that is itself a fixed parameter is not
    read as an element.

    **Raises:** `ConfigurationError` for an element of a parameter that does not exist
    or that is also swept whole; `ShapeError` for an index that does not fit the
    parameter's shape."""
    out: dict[str, tuple[str, tuple[int, ...]]] = {}
    for name in axes:
        match = _ELEMENT.match(name)
        if match is None or name in fixed:
            continue
        leaf = match.group(1)
        index = tuple(int(i) for i in match.group(2).split(","))
        if leaf not in fixed:
            raise ConfigurationError(
                f"{name!r} sweeps an element of {leaf!r}, which is not one of the fixed "
                f"parameters ({', '.join(map(repr, fixed)) or 'none'})"
            )
        if leaf in axes:
            raise ConfigurationError(
                f"{name!r} sweeps an element of {leaf!r}, which is swept whole as well: "
                f"sweep either {leaf!r} or its elements"
            )
        shape = np.shape(fixed[leaf])
        fits = len(index) == len(shape)
        if not (fits and all(-s <= i < s for i, s in zip(index, shape, strict=True))):
            raise ShapeError(
                f"{name!r}: the index {index} does not fit the parameter {leaf!r} of shape "
                f"{shape} (one index per axis, each within its length)"
            )
        out[name] = (leaf, tuple(i % s for i, s in zip(index, shape, strict=True)))
    return out


def _swept(name: str, values: Any, leaf: tuple[int, ...] | None, product: bool) -> np.ndarray:
    """The swept values of `name` as an array, checked against the shape `leaf` of the
    fixed leaf they replace (`()` for one element, `None` for a name without a fixed
    value): for `grid`, 1-D (one value per point of its axis); for `samples`, one
    entry per member along the leading axis, each of the leaf's shape (an
    array-valued parameter such as a 7-link arm's masses is swept as `(members, 7)`).

    **Raises:** `ShapeError` naming the leaf and both shapes."""
    v = np.asarray(values)
    if v.ndim == 0 or v.shape[0] == 0:
        raise ShapeError(
            f"swept values of {name!r} must be a non-empty array with one entry per "
            f"{'point of its axis' if product else 'member'}, got shape {v.shape}"
        )
    if product:
        if v.ndim != 1 or (leaf is not None and leaf != ()):
            raise ShapeError(
                f"grid() sweeps scalar parameters along 1-D axes: {name!r} got values of "
                f"shape {v.shape} for a parameter of shape {leaf}. Sweep one element of an "
                f"array-valued parameter along an axis, as grid(params, **{{'{name}[0]': "
                "values}), or the whole array with samples(params, name=values of shape "
                "(members, *shape))."
            )
        return v
    if leaf is not None and v.shape[1:] != leaf:
        raise ShapeError(
            f"swept values of {name!r} have shape {v.shape}: each member's entry has shape "
            f"{v.shape[1:]}, but the parameter {name!r} has shape {leaf}. Pass "
            f"{(v.shape[0], *leaf)} (members first, then the parameter's own shape)."
        )
    if leaf is None and v.ndim != 1:
        raise ShapeError(
            f"swept values of {name!r} must be 1-D (one value per member): it is not a "
            f"parameter of the fixed ones, so it has no shape to match; got shape {v.shape}"
        )
    return v


def grid(base: Any = None, /, *, units: Mapping[str, str] | None = None, **axes: Any) -> Grid:
    """The Cartesian product of named 1-D ranges of parameters and initial-state
    components, over fixed parameters `base`.

    `grid(params, m2=np.linspace(0.5, 2, 64), l1=np.linspace(0.5, 1.5, 64))` is a
    64 × 64 sweep: every other entry of `params` stays fixed, and the result of `sweep`
    gets dimensions `("m2", "l1")` labelled by these values. Members are ordered C-style
    (the last name varies fastest).

    A name `q0_i` sweeps component `i` of the initial coordinates, `qd0_i` of the
    initial velocities (the rest of the state is `sweep`'s `q0`, `qd0`): an amplitude
    study is `grid(params, q0_0=np.linspace(0.1, 3.0, 30))`, with a `q0_0` dimension in
    the result.

    A name with an index sweeps one element of an array-valued parameter, the rest of
    it fixed: for a 7-link arm with masses `m` of shape `(7,)`,
    `grid(params, **{"m[3]": np.linspace(1, 3, 21)})` varies the fourth link's mass,
    with a `"m[3]"` dimension in the result (an index per axis of the parameter:
    `"inertia[3, 2, 2]"`; negative indices count from the end).

    **Arguments:**

    - `base`: the fixed parameters (a dict or NamedTuple, e.g. from
      `lagrax.models.planar_2r()`).
    - `units`: the unit of each swept name (`{"m2": "kg", "q0_0": "rad"}`), set as the
      `units` attr of the result's coordinates (plots label their axes with it). An
      `xarray.DataArray` of values may carry its own `attrs["units"]` instead.
    - `**axes`: swept names and their 1-D values.

    **Returns:** a `Grid`.

    **Raises:** `ShapeError` for values that are not a non-empty 1-D array, a whole
    array-valued parameter, an element index that does not fit its parameter (and, in
    `sweep`, a state component the system does not have); `ConfigurationError` for no
    swept name, a `units` entry naming none, or an element of a parameter that does not
    exist or is also swept whole; `ArgumentTypeError` for fixed parameters that are not
    a dict or NamedTuple.
    """
    return Grid(base, axes, product=True, units=units)


def samples(base: Any = None, /, *, units: Mapping[str, str] | None = None, **values: Any) -> Grid:
    """Parameter sets and initial-state components taken member by member (no product),
    over fixed parameters `base`.

    `samples(params, m2=rng.normal(1, 0.1, 1000), r2=rng.normal(0.5, 0.02, 1000))` is a
    1000-member Monte-Carlo sweep; the result has one `"member"` dimension with `m2` and
    `r2` as coordinates along it. Names `q0_i` / `qd0_i` draw initial-state components,
    and `units` gives units, as for `grid`.

    An array-valued parameter is drawn as an array whose leading axis is the members' and
    whose other axes are the parameter's own: for a URDF arm with link masses `m` of
    shape `(7,)`, `samples(params, m=params["m"] * rng.uniform(0.8, 1.2, (1000, 7)))`
    varies every link mass by ±20 %. The result labels it with extra dimensions,
    `m (member, m_dim_0)`. A name with an index, `"m[3]"`, draws one element only, as
    for `grid`.

    **Raises:** `ShapeError` for values without members, values of a parameter whose
    per-member shape is not the parameter's (naming both), or draws of different
    lengths; otherwise as `grid`.
    """
    return Grid(base, values, product=False, units=units)


@dataclasses.dataclass(frozen=True)
class Members:
    """A sweep's members: their parameters and initial states.

    **Attributes:**

    - `grid`: the `Grid` they come from, or `None` for batched parameters.
    - `params`: without a grid, the batched parameters (every leaf a JAX array with a
      leading member axis); `None` with one.
    - `q0s`, `qd0s`: every member's initial state, `(members, n_q)` and `(members, n)`,
      of one dtype (the grid's swept state components set; `n_q = n` but on a floating
      base, whose `q` has a quaternion).
    """

    grid: Grid | None
    params: Any
    q0s: np.ndarray
    qd0s: np.ndarray

    @classmethod
    def of(cls, params: Any, q0: Any, qd0: Any) -> "Members":
        """The members of `sweep(system, q0, qd0, params)`: `params` a `Grid` or a
        pytree whose every leaf has a leading member axis, `q0`, `qd0` shared `(n,)` or
        one per member.

        **Raises:** `ShapeError` (or `ArgumentTypeError`) for batched parameters without
        members, with scalar leaves or leading axes that disagree, and for states of the
        wrong shape.
        """
        if isinstance(params, Grid):
            grid, batched, n_members = params, None, params.size
        else:
            n_members = batch_size(params)
            grid, batched = None, jtu.tree_map(jnp.asarray, params)
        q0s = _states(q0, "q0", n_members)
        qd0s = _states(qd0, "qd0", n_members)
        if grid is not None:  # swept initial-state components (q0_i / qd0_i axes)
            q0s, qd0s = grid.initial_states(q0s, qd0s)
        dtype = jnp.result_type(q0s.dtype, qd0s.dtype)
        return cls(grid, batched, q0s.astype(dtype), qd0s.astype(dtype))

    @property
    def size(self) -> int:
        """The number of members."""
        return self.q0s.shape[0]

    @property
    def dims(self) -> tuple[str, ...]:
        """The result's sweep dimensions: the grid's, or `("member",)`."""
        return self.grid.dims if self.grid is not None else ("member",)

    @property
    def shape(self) -> tuple[int, ...]:
        """The shape of the sweep dimensions."""
        return self.grid.shape if self.grid is not None else (self.size,)

    def params_of(self, start: int = 0, stop: int | None = None) -> Any:
        """Batched parameters of members `start:stop` (all by default)."""
        if self.grid is not None:
            return self.grid.params(start, stop)
        if start == 0 and stop is None:
            return self.params
        return jtu.tree_map(lambda x: x[start:stop], self.params)

    def first(self) -> Any:
        """The first member's parameters (leaves without the member axis)."""
        return jtu.tree_map(lambda x: jnp.asarray(x)[0], self.params_of(0, 1))


def _states(x: Any, name: str, n_members: int) -> np.ndarray:
    a = np.asarray(x, dtype=float if np.asarray(x).dtype.kind in "biu" else None)
    if a.ndim == 1:
        return np.broadcast_to(a, (n_members,) + a.shape)
    if a.ndim >= 2 and math.prod(a.shape[:-1]) == n_members:
        return a.reshape(n_members, a.shape[-1])
    raise ShapeError(
        f"{name} must have shape (n,) (shared by all members) or (members, n) / grid shape + "
        f"(n,) with {n_members} members; got {a.shape}"
    )
