"""The result of a sweep's chunk: `ChunkResult`, the unit a sweep computes, checkpoints
and assembles into its Dataset.

A chunk's members are solved in one compiled call (`chunk.solve_chunk`); its
`ChunkResult` is written to a checkpoint as named arrays (`ChunkResult.arrays`, read
back by `ChunkResult.from_arrays`: `checkpoint.write_chunk` and `checkpoint.prepare`),
and the chunks of a sweep, concatenated member by member (`concatenate`), become its
`xarray.Dataset` (`dataset.dataset`).
"""

from collections.abc import Mapping, Sequence
from typing import Any

import equinox as eqx
import numpy as np


class NamedArrays(eqx.Module):
    """Arrays by name, in a fixed order (a pytree whose names are static, so that
    `jax.tree_util.tree_map` and `jit` keep them and their order, where a `dict` would
    be sorted)."""

    names: tuple[str, ...] = eqx.field(static=True)
    values: tuple[Any, ...]

    def items(self) -> list[tuple[str, Any]]:
        """`(name, array)` pairs, in order."""
        return list(zip(self.names, self.values, strict=True))

    def prefixed(self, prefix: str) -> dict[str, Any]:
        """The arrays keyed `"{prefix}/{name}"` (a checkpoint's names for them)."""
        return {f"{prefix}/{k}": v for k, v in self.items()}


class ChunkResult(eqx.Module):
    """One chunk of a sweep's members (leading axis `M`): the solves and their
    post-processing (`postprocess.summary`).

    `chunk.solve_chunk` returns it on the host (NumPy arrays, `M` the chunk's members):
    members whose input was invalid carry `inf` (counters `0`) and the result code
    `RESULTS.invalid_input`. Inside the compiled chunk it holds the device's arrays, padded
    to the chunk size, before that clean-up.

    **Fields:**

    - `q`, `qd`: the kept states at the save times, `(M, T, n)` (`T = 0` with
      `keep="final"`, and where the saves only served the energy balance).
    - `energy`: the Jacobi integral `h` at those saves, `(M, T)`.
    - `energy0`, `energy_end`: `h` at the initial state and at the end, `(M,)`.
    - `energy_balance`, `energy_scale`: the numerator and the denominator of
      `Solution.energy_error` at the end, `(M,)`.
    - `q_end`, `qd_end`, `t_end`: where each solve ended, `(M, n)`, `(M, n)`, `(M,)`.
    - `result`: the `lagrax.RESULTS` code, `(M,)` int32.
    - `num_steps`, `num_accepted_steps`, `num_rejected_steps`: step counters, `(M,)`.
    - `busy_lane_steps`, `lane_steps`: lane-steps spent on members and in all (busy plus
      idle), one entry per device in the compiled chunk, `(1,)` for the chunk on the host.
    - `final_maxima`: per observable the system reports as a final maximum
      (`AbstractSystem.final_maxima`), its largest
      magnitude at the end state, `(M,)` each.
    - `event_count`, `first_event_time`: per member and event, how often it occurred and
      its first time (`inf`: never), `(M, E)`; `None` without events.
    - `reduced`: the outputs of `keep=reduce`, one array per leaf of its pytree, named by
      the leaf's path (`jax.tree_util.keystr`, e.g. `"['violation']"`), in the order of
      the pytree's leaves, `(M, ...)` each; `None` without a reduction.
    - `observed`: the system's observables that `sweep(..., observables=)` keeps, by
      name, at the saves `(M, T, ...)` or at the end `(M, ...)`; `None` without them.
    """

    q: Any
    qd: Any
    energy: Any
    energy0: Any
    energy_end: Any
    energy_balance: Any
    energy_scale: Any
    q_end: Any
    qd_end: Any
    t_end: Any
    result: Any
    num_steps: Any
    num_accepted_steps: Any
    num_rejected_steps: Any
    busy_lane_steps: Any
    lane_steps: Any
    final_maxima: NamedArrays
    event_count: Any = None
    first_event_time: Any = None
    reduced: NamedArrays | None = None
    observed: NamedArrays | None = None

    def arrays(self) -> dict[str, np.ndarray]:
        """The chunk as named arrays (the `.npz` of a checkpoint): each array field by
        its name, `final_maxima`, `reduced` and `observed` as `"final_maxima/<name>"`,
        `"reduced/<path>"` and `"observed/<name>"`, fields that are `None` left out."""
        out = dict(
            q=self.q,
            qd=self.qd,
            energy=self.energy,
            energy0=self.energy0,
            energy_end=self.energy_end,
            energy_balance=self.energy_balance,
            energy_scale=self.energy_scale,
            q_end=self.q_end,
            qd_end=self.qd_end,
            t_end=self.t_end,
            result=self.result,
            num_steps=self.num_steps,
            num_accepted_steps=self.num_accepted_steps,
            num_rejected_steps=self.num_rejected_steps,
            busy_lane_steps=self.busy_lane_steps,
            lane_steps=self.lane_steps,
        )
        if self.event_count is not None:
            out.update(event_count=self.event_count, first_event_time=self.first_event_time)
        out.update(self.final_maxima.prefixed("final_maxima"))
        if self.reduced is not None:
            out.update(self.reduced.prefixed("reduced"))
        if self.observed is not None:
            out.update(self.observed.prefixed("observed"))
        return {k: np.asarray(v) for k, v in out.items()}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> "ChunkResult":
        """The inverse of `arrays` (the named groups in the order of `arrays`' keys).

        **Raises:** `TypeError` (a field missing or unknown) or `KeyError` (an unknown
        group) for arrays that are not a chunk's.
        """
        groups: dict[str, dict[str, np.ndarray]] = {"final_maxima": {}, "reduced": {}}
        groups["observed"] = {}
        fields = {}
        for key, value in arrays.items():
            group, slash, name = key.partition("/")
            if slash:
                groups[group][name] = value
            else:
                fields[key] = value
        maxima, reduced, seen = groups["final_maxima"], groups["reduced"], groups["observed"]
        return cls(
            **fields,
            final_maxima=NamedArrays(tuple(maxima), tuple(maxima.values())),
            reduced=NamedArrays(tuple(reduced), tuple(reduced.values())) if reduced else None,
            observed=NamedArrays(tuple(seen), tuple(seen.values())) if seen else None,
        )


def concatenate(chunks: Sequence[ChunkResult]) -> ChunkResult:
    """The members of `chunks`, in order, as one `ChunkResult` (the lane-step
    counters: one entry per chunk). Arrays are matched by name, in the first chunk's
    order."""
    tables = [c.arrays() for c in chunks]
    return ChunkResult.from_arrays({k: np.concatenate([t[k] for t in tables]) for k in tables[0]})
