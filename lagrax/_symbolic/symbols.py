"""The symbols of a system's equations: coordinates, their rates, and the parameters.

- **Coordinates** are named by `coordinates=`, else by the system's `coordinate_names`,
  else `q0, q1, …`. A coordinate `theta1` has the rate `thetadot_1` and the acceleration
  `thetaddot_1`, which SymPy's LaTeX prints as `θ̇₁` and `θ̈₁` (`\\dot{\\theta}_{1}`).
  All are real.
- **Parameters** are named by their keys in `params`: `params["m1"]` is the symbol `m1`.
  An array parameter has one symbol per entry, numbered from 1 like the lecture's links:
  `params["m"]` of shape `(3,)` gives `m1, m2, m3`; `params["com"]` of shape `(2, 3)`
  gives `com1_1, com1_2, com1_3, com2_1, …`. A parameter symbol is **positive** when every
  value given for it is positive (masses, lengths, inertias, `g`: SymPy may then use
  `√(l²) = l`), and merely **real** otherwise, or when its key is in `signed=`. Keys in
  `numeric=` stay numbers (their values, exactly), which keeps the expressions of a
  spatial chain's offsets and inertia tensors small.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError
from .conversions import load_sympy, number, symbolic_array


@dataclasses.dataclass(frozen=True)
class ParameterSymbols:
    """The parameters of a derivation: `values` (the pytree passed to the energies, with
    symbols in place of the symbolic entries), `symbols` (the symbols, in the order of
    `keys`) and `keys` (`(key, index)` of each symbol in `params`)."""

    values: dict[str, Any]
    symbols: tuple[Any, ...]
    keys: tuple[tuple[str, tuple[int, ...]], ...]


def _rate_name(name: str, dots: str) -> str:
    """`theta1 -> thetadot_1` (`dots = "dot"`), `x -> xdot`: SymPy prints the suffix
    as a dot over the base."""
    from sympy.printing.conventions import split_super_sub

    base, sups, subs = split_super_sub(name)
    return base + dots + "".join("^" + s for s in sups) + "".join("_" + s for s in subs)


def coordinate_symbols(names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`(q, q̇, q̈)` as arrays of real symbols named after `names`."""
    sp = load_sympy()

    def make(fmt):
        out = np.empty(len(names), dtype=object)
        out[:] = [sp.Symbol(fmt(n), real=True) for n in names]
        return out

    return (
        make(lambda n: n),
        make(lambda n: _rate_name(n, "dot")),
        make(lambda n: _rate_name(n, "ddot")),
    )


def coordinate_names(system: Any, coordinates: Sequence[str] | None) -> tuple[str, ...]:
    """The coordinates' names (see the module docstring)."""
    n = system.n_dof
    names = coordinates if coordinates is not None else system.coordinate_names
    if names is None:
        if n is None:
            raise ConfigurationError(
                f"lagrax.symbolic needs the number of coordinates of {system.name!r}: build "
                "the system with n_dof=..., or pass coordinates=('x', 'theta', ...)"
            )
        return tuple(f"q{i}" for i in range(n))
    names = tuple(str(c) for c in names)
    if n is not None and len(names) != n:
        raise ConfigurationError(
            f"{system.name!r} has {n} coordinates but coordinates= names {len(names)}: {names}"
        )
    return names


def _numbers(key: str, value: Any) -> np.ndarray:
    """A parameter's value as a real float array, or the error naming the key."""
    try:
        arr = np.asarray(value)
    except Exception as err:  # jax arrays, lists, numbers convert; other objects do not
        raise _not_numbers(key, value) from err
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.floating)
        or np.issubdtype(arr.dtype, np.integer)
        or np.issubdtype(arr.dtype, np.bool_)
    ):
        raise _not_numbers(key, value)
    return arr.astype(np.float64)


def _not_numbers(key: str, value: Any) -> ArgumentTypeError:
    return ArgumentTypeError(
        f"lagrax.symbolic needs each entry of params to be a real number or an array of "
        f"real numbers; params[{key!r}] is {type(value).__name__} {value!r:.80}"
    )


def _symbol_name(key: str, index: tuple[int, ...]) -> str:
    if not index:
        return key
    head = f"{key}{index[0] + 1}"
    return head if len(index) == 1 else head + "_" + "_".join(str(i + 1) for i in index[1:])


def parameter_symbols(
    params: Any, signed: Sequence[str] = (), numeric: Sequence[str] = ()
) -> ParameterSymbols:
    """The symbols of `params` (see the module docstring).

    **Raises:** `ArgumentTypeError` when `params` is not a dict of numbers or arrays of
    numbers; `ConfigurationError` for a key of `signed`/`numeric` that is not in
    `params`.
    """
    sp = load_sympy()
    if not isinstance(params, Mapping) or not all(isinstance(k, str) for k in params):
        raise ArgumentTypeError(
            "lagrax.symbolic needs params as a dict of numbers (scalars or arrays) keyed by "
            f"name, the names of the symbols; got {type(params).__name__}. Convert it (a "
            "NamedTuple: params._asdict()), or write the energies on a dict"
        )
    for option, keys in (("signed", signed), ("numeric", numeric)):
        unknown = sorted(set(keys) - set(params))
        if unknown:
            raise ConfigurationError(f"{option}= names {unknown}, which are not keys of params")
    values: dict[str, Any] = {}
    symbols, where = [], []
    for key, value in params.items():
        arr = _numbers(key, value)
        if key in numeric:  # exact numbers: they cancel exactly in the expressions
            values[key] = symbolic_array(arr) if arr.ndim else number(arr)
            continue
        entries = np.empty(arr.shape, dtype=object)
        positive = bool(np.all(arr > 0)) and key not in signed
        for index in np.ndindex(*arr.shape):
            name = _symbol_name(key, index)
            entries[index] = sp.Symbol(name, **({"positive": True} if positive else {"real": True}))
            symbols.append(entries[index])
            where.append((key, index))
        values[key] = entries if arr.ndim else entries[()]
    return ParameterSymbols(values, tuple(symbols), tuple(where))


def check_unique(symbols: Sequence[Any]) -> dict[str, Any]:
    """`{name: symbol}`, or a `ConfigurationError` when two symbols share a name."""
    table: dict[str, Any] = {}
    for s in symbols:
        if s.name in table:
            raise ConfigurationError(
                f"two symbols are named {s.name!r} (a parameter key, an entry of an array "
                "parameter or a coordinate): rename one, e.g. with coordinates=(...)"
            )
        table[s.name] = s
    return table
