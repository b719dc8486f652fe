"""The result of a sweep as an `xarray.Dataset`, from its chunks' `ChunkResult`s."""

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._core.results import RESULTS, code_of, messages
from .grid import Members
from .options import Kept
from .result import ChunkResult, concatenate

_OK = int(code_of(RESULTS.successful))
_EVENT = int(code_of(RESULTS.event_occurred))  # a stop at a terminal event: ok


def dataset(
    chunks: Sequence[ChunkResult],
    members: Members,
    kept: Kept,
    *,
    dof: np.ndarray,
    attrs: Mapping[str, Any],
    q_dof: np.ndarray | None = None,
):
    """The `xarray.Dataset` of a sweep (see `sweep`'s **Returns**).

    **Arguments:**

    - `chunks`: the chunks' results, in member order.
    - `members`: the sweep's members (their grid or batched parameters label them).
    - `kept`: what was kept per member (`keep=`).
    - `dof`: the labels of the `dof` coordinate (the system's coordinate names, or
      `0 … n−1`): the velocities' `qd` (and `q`'s where the two have one size).
    - `q_dof`: the labels of `q`'s own `q_dof` coordinate where `q` and `qd` differ in
      size (a floating base: the system's `configuration_names`), else `None`.
    - `attrs`: how the sweep ran (solver, tolerances, interval, schedule, devices, the
      cut), put into the Dataset's `attrs` after the failure counts.

    **Returns:** the `xarray.Dataset`.
    """
    import xarray as xr

    cat = concatenate(chunks)
    data = variables(cat, kept, list(members.dims), _shaper(members))
    # the system's coordinate names (a tree's joint names) label the dof axis
    coords: dict[str, Any] = {"dof": dof, **labels(members, kept)}
    if q_dof is not None and kept.mode != "reduce":
        coords["q_dof"] = q_dof
    ok = data["ok"][1].reshape(-1)
    stats = attrs_of(cat.result, ok, cat.busy_lane_steps, cat.lane_steps, members.size, attrs)
    return xr.Dataset(data, coords=coords, attrs=stats)


def variables(
    cat: ChunkResult, kept: Kept, dims: list[str], shaped: Any, *, status: bool = True
) -> dict[str, Any]:
    """The Dataset's variables of members `cat` (dimensions `dims`, each array put
    into their shape by `shaped`): what was kept and the outcomes, with long names for
    plots. A sweep store (`store.SweepStore`) writes them chunk by chunk with one flat
    `"member"` dimension and no `status` (`status=False`: it is derived from `result`
    when the store is opened)."""
    ok = (cat.result == _OK) | (cat.result == _EVENT)
    data = _kept_variables(cat, dims, shaped, kept, ok)
    data.update(_outcomes(cat, dims, shaped, ok, status))
    _name_for_plots(data, final=kept.mode == "final")
    return data


def labels(members: Members, kept: Kept) -> dict[str, Any]:
    """The coordinates of a sweep's Dataset beside `dof`: the kept times and the
    members' labels (`member_labels`)."""
    coords: dict[str, Any] = {}
    if kept.path:
        coords["time"] = ("time", kept.ts, {"units": "s"})
    coords.update(member_labels(members))
    return coords


def _kept_variables(cat: ChunkResult, dims: list[str], shaped, kept: Kept, ok) -> dict[str, Any]:
    """`q`, `qd` and `energy` at the end (`keep="final"`, `inf` for a failed member) or
    at the saves, with the kept observables (`observables=`, by name, their dimensions
    the system's `observable_dims`); or the outputs of `reduce`, each named by its
    pytree path."""
    data: dict[str, Any] = {}
    q_dim = q_dof_dim(cat.q_end.shape[-1], cat.qd_end.shape[-1])
    if kept.mode == "final":
        at_t1 = ok[:, None]
        data["q"] = (dims + [q_dim], shaped(np.where(at_t1, cat.q_end, np.inf)))
        data["qd"] = (dims + ["dof"], shaped(np.where(at_t1, cat.qd_end, np.inf)))
        data["energy"] = (dims, shaped(np.where(ok, cat.energy_end, np.inf)))
    elif kept.mode == "path":
        data["q"] = (dims + ["time", q_dim], shaped(cat.q))
        data["qd"] = (dims + ["time", "dof"], shaped(cat.qd))
        data["energy"] = (dims + ["time"], shaped(cat.energy))
    if kept.mode != "reduce" and cat.observed is not None:  # sweep(..., observables=)
        at = ["time"] if kept.mode == "path" else []
        for (name, value), (_, own) in zip(cat.observed.items(), kept.observed, strict=True):
            if not at:  # at the end: `inf` for a failed member, like q
                value = np.where(ok.reshape(ok.shape + (1,) * (value.ndim - 1)), value, np.inf)
            data[name] = (dims + at + list(own), shaped(value))
    if kept.mode == "reduce":
        for path, value in cat.reduced.items() if cat.reduced is not None else ():
            name = _reduce_name(path)
            x = shaped(value)
            extra = [f"{name}_dim_{k}" for k in range(x.ndim - len(dims))]
            data[name] = (dims + extra, x)
    return data


def q_dof_dim(n_q: int, n_v: int) -> str:
    """The dimension of `q`'s coordinates: `"dof"`, shared with `qd`, where the two have
    one size; `"q_dof"` where they differ (a floating base: `7 + n` against `6 + n`)."""
    return "dof" if n_q == n_v else "q_dof"


def _outcomes(cat: ChunkResult, dims: list[str], shaped, ok, status: bool) -> dict[str, Any]:
    """The energy error and change, the result and its message (with `status`), the
    final maxima, the events and the step counters, per member."""
    data: dict[str, Any] = {}
    # as Solution.energy_error: the balance residual h − h0 − W over the scale
    # max(|h0|, |T| + |V|) (see postprocess.energy_balance), and the change of h itself
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = cat.energy_balance / np.maximum(cat.energy_scale, np.finfo(float).tiny)
        change = cat.energy_end - cat.energy0  # inf − inf where invalid: masked
    data["energy_error"] = (dims, shaped(np.where(ok, rel, np.inf)))
    data["energy_change"] = (dims, shaped(np.where(ok, change, np.inf)))
    data["ok"] = (dims, shaped(ok))
    data["result"] = (dims, shaped(cat.result))
    if status:
        data["status"] = (dims, shaped(statuses(cat.result)))
    for k, value in cat.final_maxima.items():  # e.g. max |φ(q)| at the end
        data[k] = (dims, shaped(value))
    if cat.event_count is not None:  # per member and event (simulate's Solution.events)
        data["event_count"] = (dims + ["event"], shaped(cat.event_count))
        data["first_event_time"] = (dims + ["event"], shaped(cat.first_event_time))
    data["t_end"] = (dims, shaped(cat.t_end), {"units": "s"})
    data["num_steps"] = (dims, shaped(cat.num_steps))
    data["num_accepted_steps"] = (dims, shaped(cat.num_accepted_steps))
    data["num_rejected_steps"] = (dims, shaped(cat.num_rejected_steps))
    return data


def _name_for_plots(data: dict[str, Any], final: bool) -> None:
    """Long names for plots' labels (units only where lagrax knows them)."""
    when = "final " if final else ""
    for k, long_name in (
        ("q", f"{when}q"),
        ("qd", f"{when}q̇"),
        ("energy", f"{when}energy h"),
        ("energy_error", "relative energy error"),
        ("num_steps", "solver steps"),
    ):
        if k in data:
            data[k] = data[k][:2] + (
                {**(data[k][2] if len(data[k]) > 2 else {}), "long_name": long_name},
            )


def member_labels(members: Members) -> dict[str, Any]:
    """The coordinates along the sweep dimensions: a grid's swept values (with their
    units; an initial-state component's long name), or the member index and the
    batched scalar parameters that vary between members."""
    coords: dict[str, Any] = {}
    grid = members.grid
    if grid is None:
        coords["member"] = np.arange(members.size)
        if isinstance(members.params, Mapping):  # per-member scalar parameters
            for k, v in members.params.items():
                v = np.asarray(v)
                if v.ndim == 1 and not np.all(v == v[0]):
                    coords[k] = ("member", v)
        return coords
    for k, v in grid.axes.items():
        attrs = {"units": grid.units[k]} if k in grid.units else {}
        if k in grid.states:
            which, i = grid.states[k]
            attrs["long_name"] = f"initial {'q' if which == 'q0' else 'q̇'}[{i}]"
        # an array-valued parameter's draws, (members, *shape): one more dimension per
        # axis of the leaf, e.g. ("member", "m_dim_0") for the masses of a 7-link arm
        extra = [f"{k}_dim_{i}" for i in range(v.ndim - 1)]
        coords[k] = ((k if grid.product else "member", *extra), v, attrs)
    return coords


def attrs_of(result, ok, busy_lane_steps, lane_steps, n_members: int, run: Mapping[str, Any]):
    """The Dataset's `attrs`: the member and failure counts (from every member's
    `result` and `ok`), how the sweep ran (`run`) and the share of lane-steps that were
    idle (from the chunks' lane-step counters)."""
    text = messages()
    failed = ~ok
    counts = {}
    for r in np.unique(result[failed]):
        counts[short_label(text[r])] = int(np.sum(result == r))
    busy, total = int(np.sum(busy_lane_steps)), int(np.sum(lane_steps))
    return dict(
        n_members=int(n_members),
        n_failed=int(failed.sum()),
        failures=json.dumps(counts),
        **run,
        lane_idle_fraction=float(1 - busy / total) if total else 0.0,
    )


def statuses(result: np.ndarray) -> np.ndarray:
    """Each member's status: `"ok"`, or its result's message (first line)."""
    text = messages()
    return np.asarray(
        [
            "ok"
            if r == _OK
            else "ok: stopped at a terminal event"
            if r == _EVENT
            else short_label(text[r])
            for r in result
        ]
    )


def _shaper(members: Members):
    """Reshape a per-member array `(members, ...)` to the sweep's shape `(*shape, ...)`."""
    shape = members.shape
    return lambda x: x.reshape(shape + x.shape[1:])


def _reduce_name(path: str) -> str:
    name = path.strip("[]'\".").replace("']['", "_").replace("][", "_")
    return name or "value"


def short_label(message: str) -> str:
    return message.split("\n")[0].strip()
