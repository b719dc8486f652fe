"""The result of a sweep as an `xarray.Dataset`."""

import json
from collections.abc import Mapping

import numpy as np

from .._core.results import RESULTS, code_of, messages

_OK = int(code_of(RESULTS.successful))
_EVENT = int(code_of(RESULTS.event_occurred))  # a stop at a terminal event: ok


def dataset(
    xr,
    chunks,
    batch,
    raw_params,
    ts,
    keep,
    n,
    n_members,
    settings,
    solver,
    rtol,
    atol,
    schedule,
    n_dev,
    cut,
    names=None,
):
    cat = {
        k: np.concatenate([c[k] for c in chunks])
        for k in chunks[0]
        if k not in ("busy_lane_steps", "lane_steps", "__reduce_paths__")
    }
    busy = sum(int(c["busy_lane_steps"].sum()) for c in chunks)
    total = sum(int(c["lane_steps"].sum()) for c in chunks)
    if batch is not None:
        dims, shape = batch.dims, batch.shape
    else:
        dims, shape = ("member",), (n_members,)

    def shaped(x):
        return x.reshape(shape + x.shape[1:])

    sweep_dims = list(dims)
    data = {}
    final = isinstance(keep, str) and keep == "final"
    time_dims = [] if final else ["time"]
    ok = (cat["result"] == _OK) | (cat["result"] == _EVENT)
    if final:
        at_t1 = ok[:, None]
        data["q"] = (sweep_dims + ["dof"], shaped(np.where(at_t1, cat["q_end"], np.inf)))
        data["qd"] = (sweep_dims + ["dof"], shaped(np.where(at_t1, cat["qd_end"], np.inf)))
        data["energy"] = (sweep_dims, shaped(np.where(ok, cat["energy_end"], np.inf)))
    elif not callable(keep):
        data["q"] = (sweep_dims + time_dims + ["dof"], shaped(cat["q"]))
        data["qd"] = (sweep_dims + time_dims + ["dof"], shaped(cat["qd"]))
        data["energy"] = (sweep_dims + time_dims, shaped(cat["energy"]))
    else:
        paths = [str(p) for p in chunks[0]["__reduce_paths__"]]
        for p in paths:
            name = _reduce_name(p)
            x = shaped(cat["reduce" + p])
            extra = [f"{name}_dim_{k}" for k in range(x.ndim - len(sweep_dims))]
            data[name] = (sweep_dims + extra, x)
    # as Solution.energy_error: the balance residual h − h0 − W over the scale
    # max(|h0|, |T| + |V|) (see _chunk._energy_balance), and the change of h itself
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = cat["energy_balance"] / np.maximum(cat["energy_scale"], np.finfo(float).tiny)
        change = cat["energy_end"] - cat["energy0"]  # inf − inf where invalid: masked
    data["energy_error"] = (sweep_dims, shaped(np.where(ok, rel, np.inf)))
    data["energy_change"] = (sweep_dims, shaped(np.where(ok, change, np.inf)))
    data["ok"] = (sweep_dims, shaped(ok))
    data["result"] = (sweep_dims, shaped(cat["result"]))
    text = messages()
    status = np.asarray(
        [
            "ok"
            if r == _OK
            else "ok: stopped at a terminal event"
            if r == _EVENT
            else _short(text[r])
            for r in cat["result"]
        ]
    )
    data["status"] = (sweep_dims, shaped(status))
    for k in ("constraint_violation", "velocity_constraint_violation"):
        if k in cat:
            data[k] = (sweep_dims, shaped(cat[k]))
    if "event_count" in cat:  # per member and event (simulate's Solution.events)
        data["event_count"] = (sweep_dims + ["event"], shaped(cat["event_count"]))
        data["first_event_time"] = (sweep_dims + ["event"], shaped(cat["first_event_time"]))
    for k in ("t_end", "num_steps", "num_accepted_steps", "num_rejected_steps"):
        data[k] = (sweep_dims, shaped(cat[k]))
    data["t_end"] = (sweep_dims, shaped(cat["t_end"]), {"units": "s"})
    # names for plots' labels (units only where lagrax knows them)
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
    # the system's coordinate names (a tree's joint names) label the dof axis
    coords = {"dof": np.arange(n) if names is None else np.asarray(names, dtype=str)}
    if not final and not callable(keep):
        coords["time"] = ("time", ts, {"units": "s"})
    if batch is not None:
        for k, v in batch.axes.items():
            attrs = {"units": batch.units[k]} if k in batch.units else {}
            if k in batch.states:
                which, i = batch.states[k]
                attrs["long_name"] = f"initial {'q' if which == 'q0' else 'q̇'}[{i}]"
            coords[k] = (k if batch.product else "member", v, attrs)
    else:
        coords["member"] = np.arange(n_members)
        if isinstance(raw_params, Mapping):  # per-member scalar parameters label the members
            for k, v in raw_params.items():
                v = np.asarray(v)
                if v.ndim == 1 and not np.all(v == v[0]):
                    coords[k] = ("member", v)
    failed = ~ok
    counts = {}
    for r in np.unique(cat["result"][failed]):
        counts[_short(text[r])] = int(np.sum(cat["result"] == r))
    attrs = dict(
        n_members=int(n_members),
        n_failed=int(failed.sum()),
        failures=json.dumps(counts),
        solver=type(solver).__name__,
        rtol=float(rtol),
        atol=float(atol),
        t0=settings["t0"],
        t1=settings["t1"],
        schedule=schedule,
        devices=int(n_dev),
        **cut,
        lane_idle_fraction=float(1 - busy / total) if total else 0.0,
    )
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _reduce_name(path: str) -> str:
    name = path.strip("[]'\".").replace("']['", "_").replace("][", "_")
    return name or "value"


def _short(message: str) -> str:
    return message.split("\n")[0].strip()
