"""The batch of a sweep: ``Grid``, ``grid`` and ``samples``."""

import math
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
import numpy as np

from .._errors import ArgumentTypeError, ConfigurationError, ShapeError


class Grid:
    """A batch of parameter sets with labels: fixed values plus swept ones.

    Made by :func:`grid` (the Cartesian product of named 1-D ranges: one sweep dimension
    per name) or :func:`samples` (named values taken together, member by member: one
    ``"member"`` dimension, e.g. Monte-Carlo draws). ``sweep`` labels its results with
    these names and values.

    **Attributes:** ``base`` (the fixed parameters), ``axes`` (name → 1-D values),
    ``dims`` (the result's sweep dimensions), ``shape``, ``size`` (number of members).
    """

    def __init__(self, base: Any, axes: Mapping[str, np.ndarray], product: bool):
        if base is None:
            base = {}
        if not (isinstance(base, Mapping) or hasattr(base, "_replace")):
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
        for name, values in axes.items():
            v = np.asarray(values)
            if v.ndim != 1 or v.size == 0:
                raise ShapeError(
                    f"swept values of {name!r} must be a non-empty 1-D array, got shape {v.shape}"
                )
            self.axes[name] = v
        self.product = product
        if product:
            self.dims = tuple(self.axes)
            self.shape = tuple(v.size for v in self.axes.values())
        else:
            sizes = {k: v.size for k, v in self.axes.items()}
            if len(set(sizes.values())) != 1:
                raise ShapeError(f"samples() needs values of one length per name, got {sizes}")
            self.dims = ("member",)
            self.shape = (next(iter(sizes.values())),)
        self.size = math.prod(self.shape)

    def __repr__(self) -> str:
        kind = "grid" if self.product else "samples"
        return f"Grid({kind}, dims={self.dims}, shape={self.shape}, swept={list(self.axes)})"

    def columns(self, start: int = 0, stop: int | None = None) -> dict[str, np.ndarray]:
        """The swept values of members ``start:stop`` (C order over the grid)."""
        stop = self.size if stop is None else stop
        if not self.product:
            return {k: v[start:stop] for k, v in self.axes.items()}
        idx = np.unravel_index(np.arange(start, stop), self.shape)
        return {k: v[i] for (k, v), i in zip(self.axes.items(), idx, strict=True)}

    def params(self, start: int = 0, stop: int | None = None) -> Any:
        """Batched parameters of members ``start:stop``: every leaf has a leading axis."""
        stop = self.size if stop is None else stop
        cols = self.columns(start, stop)
        n = stop - start
        fixed = dict(self.base) if isinstance(self.base, Mapping) else self.base._asdict()
        out = {}
        for k, v in fixed.items():
            if k not in cols:
                v = jnp.asarray(v)
                out[k] = jnp.broadcast_to(v, (n,) + v.shape)
        for k, v in cols.items():
            out[k] = jnp.asarray(v)
        if isinstance(self.base, Mapping):
            return out
        unknown = set(cols) - set(fixed)
        if unknown:
            raise ConfigurationError(
                f"{sorted(unknown)} are not fields of {type(self.base).__name__}"
            )
        return type(self.base)(**out)


def grid(base: Any = None, /, **axes: Any) -> Grid:
    """The Cartesian product of named 1-D parameter ranges, over fixed parameters ``base``.

    ``grid(params, m2=np.linspace(0.5, 2, 64), l1=np.linspace(0.5, 1.5, 64))`` is a
    64 × 64 sweep: every other entry of ``params`` stays fixed, and the result of
    :func:`sweep` gets dimensions ``("m2", "l1")`` labelled by these values. Members are
    ordered C-style (the last name varies fastest).

    **Arguments:** ``base``: the fixed parameters (a dict or NamedTuple, e.g. from
    ``lagrax.models.planar_2r()``); ``**axes``: swept names and their 1-D values.

    **Returns:** a :class:`Grid`.
    """
    return Grid(base, axes, product=True)


def samples(base: Any = None, /, **values: Any) -> Grid:
    """Parameter sets taken member by member (no product), over fixed parameters ``base``.

    ``samples(params, m2=rng.normal(1, 0.1, 1000), r2=rng.normal(0.5, 0.02, 1000))`` is a
    1000-member Monte-Carlo sweep; the result has one ``"member"`` dimension with ``m2``
    and ``r2`` as coordinates along it.
    """
    return Grid(base, values, product=False)
