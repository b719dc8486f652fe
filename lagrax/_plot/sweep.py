"""Figures of a sweep: `sweep_heatmap`, a per-member quantity over a 1-D or 2-D
`lagrax.sweep` grid (public as `lagrax.plot.sweep_heatmap`)."""

from typing import Any

import numpy as np

from .._core.errors import ShapeError
from .axes import axes_for

# how a failed member is drawn: a grey, hatched cell or band
_HATCH = dict(facecolor="0.8", edgecolor="0.35", hatch="///", lw=0)


def sweep_heatmap(
    ds: Any,
    var: Any,
    *,
    dof: int | str | None = None,
    x: str | None = None,
    y: str | None = None,
    log: bool = False,
    cmap: str = "viridis",
    label: str | None = None,
    ax=None,
):
    """A per-member quantity over a 1-D or 2-D grid from `lagrax.sweep`.

    Over a 2-D grid: a heat map, cells centred on the swept values, with a colour bar.
    Over a 1-D grid: a line through the members' values against the swept value. Axes
    are labelled with the swept names and their units (the coordinates'
    `attrs["units"]`, set by `lagrax.grid(..., units=...)`); log-spaced values get a log
    axis. Members that failed (`ds.ok` False) or whose value is not finite are drawn
    grey and hatched (a cell, or a band over a 1-D grid), and counted in the legend, so a
    failure never looks like a number.

    **Arguments:**

    - `ds`: the `xarray.Dataset` of a sweep over a `lagrax.grid` of one or two names.
    - `var`: a variable name of `ds` (`"energy_error"`, `"num_steps"`, `"q"`, a `keep=`
      function's output, …) or an `xarray.DataArray` over the sweep dimensions (e.g.
      `abs(ds.q.sel(dof=1) - ref)`).
    - `dof`: the coordinate to show when `var` has a `"dof"` dimension.
    - `x`, `y`: which sweep dimension goes on which axis of a 2-D grid (default: the
      grid's second dimension on x, its first on y, as `xarray`'s own `.plot()`).
    - `log`: logarithmic colour scale (2-D) or y axis (1-D); non-positive values are
      then marked as failed.
    - `cmap`, `label`: colour map; label of the value (default: the variable's name and
      its `attrs["units"]`).
    - `ax`: axes to draw on (default: a new figure).

    **Returns:** the axes. 2-D: its first collection is the `QuadMesh` whose array has
    the grid's shape `(len(y), len(x))`. 1-D: `ax.lines[0]` holds the values against the
    swept values (failed members left out).

    **Raises:** `ShapeError` when `var` has more than the sweep dimensions left (the
    message names the dimensions to select or reduce), or a `"dof"` dimension and no
    `dof=`.
    """
    from matplotlib.patches import Patch

    da, name = _selected(ds, var, dof)
    ok = None
    if "ok" in getattr(ds, "data_vars", {}) and set(ds["ok"].dims) == set(da.dims):
        ok = ds["ok"]
    ax = axes_for(ax)
    if da.ndim == 1:
        bad = _line(ax, da, ok, log, _value_label(da, name, label, dof))
    else:
        bad = _mesh(ax, da, ok, x, y, log, cmap, _value_label(da, name, label, dof))
    if bad.any():
        ax.legend(
            handles=[Patch(**_HATCH, label=f"failed ({int(bad.sum())} of {bad.size})")],
            loc="upper right",
            fontsize=8,
        )
    return ax


def _selected(ds: Any, var: Any, dof: int | str | None) -> tuple[Any, Any]:
    """`(values, name)` of `var` over the sweep dimensions, its `dof` selected, or a
    `ShapeError` that says which dimensions to select or reduce."""
    da = ds[var] if isinstance(var, str) else var
    name = var if isinstance(var, str) else (da.name or "value")
    if "dof" in da.dims:
        if dof is None:
            raise ShapeError(
                f"{name!r} has a 'dof' dimension: choose a coordinate with dof= (one of "
                f"{list(np.asarray(da['dof'].values))})"
            )
        da = da.sel(dof=dof)
    if da.ndim not in (1, 2):
        extra = [d for d in da.dims if d == "time" or "_dim_" in d]
        if "time" in extra:
            hint = f"select a time first, e.g. ds[{name!r}].isel(time=-1)"
        elif extra:
            hint = f"select or reduce {extra} first, e.g. .isel({extra[0]}=0)"
        else:
            hint = f"select values of all but one or two of them first, e.g. .sel({da.dims[0]}=...)"
        raise ShapeError(
            f"sweep_heatmap draws a 1-D or 2-D grid; {name!r} has dimensions {da.dims}: {hint}"
        )
    return da, name


def _failed(values: np.ndarray, ok: Any, log: bool) -> np.ndarray:
    """Members drawn as failed: not finite, `ok` false, or not positive on a log scale."""
    bad = ~np.isfinite(values)
    if ok is not None:
        bad |= ~np.asarray(ok.values, dtype=bool)
    if log:
        with np.errstate(invalid="ignore"):
            bad |= ~(values > 0)
    return bad


def _line(ax, da: Any, ok: Any, log: bool, value_label: str) -> np.ndarray:
    """A 1-D grid: the values against the swept value, failed members as hatched
    bands. Returns which members failed."""
    (xd,) = da.dims
    values = np.asarray(da.values, dtype=float)
    bad = _failed(values, ok, log)
    xs = _axis_values(da, xd)
    xe, xlog = _edges(xs)
    ax.plot(xs[~bad], values[~bad], "-o", ms=3, lw=1.2)
    for i in np.nonzero(bad)[0]:
        ax.axvspan(xe[i], xe[i + 1], **_HATCH)
    if xlog:
        ax.set_xscale("log")
    if log:
        ax.set_yscale("log")
    ax.set_xlim(xe[0], xe[-1])
    ax.set_xlabel(_coord_label(da, xd))
    ax.set_ylabel(value_label)
    ax.grid(True, alpha=0.3)
    return bad


def _mesh(ax, da: Any, ok: Any, x, y, log: bool, cmap: str, value_label: str) -> np.ndarray:
    """A 2-D grid: a heat map with a colour bar, failed members as hatched cells.
    Returns which members failed, in the drawn `(y, x)` order."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Rectangle

    if x is None and y is None:
        y, x = da.dims
    elif x is None or y is None:
        x = x if x is not None else next(d for d in da.dims if d != y)
        y = y if y is not None else next(d for d in da.dims if d != x)
    da = da.transpose(y, x)
    values = np.asarray(da.values, dtype=float)
    bad = _failed(values, None if ok is None else ok.transpose(y, x), log)
    data = np.ma.masked_array(values, bad)
    (xe, xlog), (ye, ylog) = _edges(_axis_values(da, x)), _edges(_axis_values(da, y))
    colours = plt.get_cmap(cmap).with_extremes(bad="0.8")
    norm = LogNorm() if log and not bad.all() else None
    mesh = ax.pcolormesh(xe, ye, data, cmap=colours, norm=norm, shading="flat")
    ax.figure.colorbar(mesh, ax=ax, label=value_label)
    if xlog:
        ax.set_xscale("log")
    if ylog:
        ax.set_yscale("log")
    for j, i in zip(*np.nonzero(bad), strict=True):
        ax.add_patch(Rectangle((xe[i], ye[j]), xe[i + 1] - xe[i], ye[j + 1] - ye[j], **_HATCH))
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(_coord_label(da, x))
    ax.set_ylabel(_coord_label(da, y))
    return bad


def _edges(centres: np.ndarray) -> tuple[np.ndarray, bool]:
    """Cell edges around grid values (geometric midpoints for log-spaced values)."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5]), False
    log = bool(np.all(c > 0) and c.size > 2)
    if log:
        d = np.diff(np.log(c))
        log = bool(np.allclose(d, d[0], rtol=1e-6)) and not np.allclose(
            np.diff(c), c[1] - c[0], rtol=1e-6
        )
    x = np.log(c) if log else c
    mid = 0.5 * (x[1:] + x[:-1])
    e = np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])
    return (np.exp(e) if log else e), log


def _coord_label(da: Any, dim: str) -> str:
    """`name [units]` of a sweep dimension, from its coordinate's attrs."""
    attrs = da[dim].attrs if dim in da.coords else {}
    name = attrs.get("long_name", dim)
    if name != dim:
        name = f"{name} ({dim})"
    unit = attrs.get("units")
    return f"{name} [{unit}]" if unit else name


def _value_label(da: Any, name: str, label: str | None, dof: Any = None) -> str:
    """The label of the drawn value: `label`, else its long name (or name), its
    coordinate `[dof]` and `[units]` from its attrs."""
    if label:
        return label
    name = da.attrs.get("long_name", name)
    if dof is not None:
        name = f"{name}[{dof}]"
    unit = da.attrs.get("units")
    return f"{name} [{unit}]" if unit else name


def _axis_values(da: Any, dim: str) -> np.ndarray:
    c = np.asarray(da[dim].values) if dim in da.coords else np.arange(da.sizes[dim])
    return c if np.issubdtype(c.dtype, np.number) else np.arange(c.size)
