"""How a sweep cuts its batch: members per chunk and lanes per device, from the device.

A pure function of a few numbers (`plan`), so that the choice is unit-tested
without the device it is made for; `device_info` reads those numbers from JAX.

- **CPU**: chunks of up to 8,192 members (fewer when the kept output is large: about
  64 MiB of it per chunk), on 16 lanes per device (fewer for a smaller chunk), refilled
  one member at a time. A CPU core runs one lane after another: a few lanes amortize the
  loop's control over SIMD-wide arithmetic, and more only spill the lanes' state out of
  the cache (on the 2-core development machine, 16 lanes against the 128–256 of an
  eighth of the chunk: 2R arm 1.13× faster, 7-DOF arm 1.5×, 4-link chain 1.2×). A
  compiled chunk runs
  on one core: with one CPU device and `threads` cores, the chunks run `threads` at a
  time (`driver._run`), so the batch is cut into a multiple of `threads` chunks of
  equal size (each core gets its share, and no chunk is mostly padding).
- **GPU / TPU**: a step costs about the same on a few thousand lanes as on one, so lanes
  should fill the device: up to `MAX_LANES` per device (on an H100 the 2R arm's
  throughput still grew from 32k to 131k lanes, and barely beyond), fewer when the
  device memory (`memory_stats()["bytes_limit"]`; `FALLBACK_MEMORY` when JAX
  does not say) or the members cannot fill them. A chunk holds
  `MEMBERS_PER_LANE` members per lane, so that freed lanes have members to take
  (the whole batch in one chunk, when it is smaller); refills are a 32nd of the lanes,
  and from `TAIL_MIN_LANES` lanes on, the last members finish on a quarter of the
  lanes (`tail_lanes`). With these, the 2R arm's sweep of 524k members (131k lanes)
  idles about 11 % of its lane-steps, against 22 % with the CPU's refill and no tail
  loop (counted from its members' step counts by
  `benchmarks/bench_sweep_gpu.py --schedule`).
"""

import dataclasses
import math
import os
from collections.abc import Sequence
from typing import Any

import jax

#: lanes per accelerator at most (2R arm on an H100: 124k traj/s at 131k lanes, 60k at 32k)
MAX_LANES = 1 << 17
#: members per lane in an accelerator's chunk (the queue then has members to refill with)
MEMBERS_PER_LANE = 4
#: device memory assumed when JAX does not report it (bytes)
FALLBACK_MEMORY = 4 << 30
#: share of the device memory a chunk may plan on (lanes and kept output, half each)
MEMORY_SHARE = 0.5
#: lanes per device from which the last members finish on a narrower loop (its extra
#: compiled loop body costs about half the compile time again: worth it only for chunks
#: that take seconds)
TAIL_MIN_LANES = 1 << 16

# CPU: today's choices
_CPU_MAX_CHUNK = 8192
_CPU_MIN_CHUNK = 64
_CPU_OUTPUT_BYTES = 64 << 20
_CPU_LANES = 16


@dataclasses.dataclass(frozen=True)
class DeviceInfo:
    """What the defaults depend on: the platform (`"cpu"`, `"gpu"`, `"tpu"`), the
    memory of one device in bytes (`None`: unknown) and the number of devices the
    batch is sharded over."""

    platform: str
    memory: int | None
    count: int
    #: chunks run at once on the host (the cores, with one CPU device; else 1)
    threads: int = 1


@dataclasses.dataclass(frozen=True)
class Plan:
    """The chosen cut: `chunk_size` members per compiled call (a whole number per
    device), `n_lanes` lanes per device, `refill` members started per refill and the
    width of the tail loop (`tail_lanes`; 0: none), see `lanes.run_lanes`; `threads`
    chunks run at once."""

    chunk_size: int
    n_lanes: int
    refill: int
    tail_lanes: int
    threads: int = 1


def host_cores() -> int:
    """The CPU cores this process may run on (its affinity mask where the OS has one:
    a batch job's or container's share, not the whole machine)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - macOS and Windows have no affinity mask
        return max(1, os.cpu_count() or 1)


def device_info(devices: Sequence[Any]) -> DeviceInfo:
    """`DeviceInfo` of `devices` (JAX devices, all of one kind): with one CPU device in
    a single-process run, the chunks may run on all the host's cores (`host_cores`);
    several CPU devices (`--xla_force_host_platform_device_count`) already share the
    cores out, and an accelerator runs one chunk at a time."""
    first = devices[0]
    platform = str(getattr(first, "platform", "cpu")).lower()
    if platform in ("cuda", "rocm"):
        platform = "gpu"
    memory = None
    try:
        stats = first.memory_stats()
    except Exception:  # a backend without memory statistics (CPU, some plugins)
        stats = None
    if stats:
        limit = stats.get("bytes_limit")
        if isinstance(limit, int) and limit > 0:
            memory = limit
    count = max(1, len(devices))
    threads = 1
    if platform == "cpu" and count == 1 and jax.process_count() == 1:
        threads = host_cores()
    return DeviceInfo(platform, memory, count, threads)


def lane_bytes(n_dof: int, n_params: int, itemsize: int) -> int:
    """A generous estimate of the device memory one lane needs: its solver state and
    stages (about 40 vectors of the state's `2n` entries), the `n x n` matrices of
    the dynamics (mass matrix, its factor, autodiff temporaries), its parameters; twice,
    for the loop's double buffering, and twice again for XLA's temporaries."""
    words = 40 * n_dof + 10 * n_dof * n_dof + n_params + 32
    return 4 * words * itemsize


def plan(
    info: DeviceInfo,
    *,
    n_members: int,
    member_bytes: int,
    lane_bytes: int,
    chunk_size: int | None = None,
    n_lanes: int | None = None,
) -> Plan:
    """Members per chunk and lanes per device for a sweep of `n_members` on `info`.

    **Arguments:**

    - `info`: the devices (`device_info`).
    - `n_members`: members in the sweep.
    - `member_bytes`: memory per member of a chunk's inputs and kept output.
    - `lane_bytes`: memory per lane (`lane_bytes`).
    - `chunk_size`, `n_lanes`: the user's choices (already validated), kept as given
      (`chunk_size` at most the members, rounded up to a whole number per device).

    **Returns:** a `Plan`.
    """
    count = max(1, info.count)
    per_device_members = -(-n_members // count)
    accelerator = info.platform != "cpu"
    if chunk_size is None:
        if not accelerator:
            chunk = min(_CPU_MAX_CHUNK, max(_CPU_MIN_CHUNK, _CPU_OUTPUT_BYTES // member_bytes))
            chunk = min(chunk, n_members)
            if info.threads > 1:  # a multiple of `threads` chunks, of equal size
                chunks = -(-n_members // chunk)
                chunks = -(-chunks // info.threads) * info.threads
                chunk = -(-n_members // chunks)
        else:
            budget = int((info.memory or FALLBACK_MEMORY) * MEMORY_SHARE) // 2
            lanes_fit = _lanes_fit(budget, lane_bytes)
            per_device = min(
                per_device_members,
                MEMBERS_PER_LANE * (n_lanes or lanes_fit),
                max(1, budget // max(1, member_bytes)),
            )
            chunk = max(per_device, min(n_lanes or 1, per_device_members)) * count
    else:
        chunk = min(chunk_size, n_members)
    chunk = -(-chunk // count) * count  # a whole number of members per device
    per_device = chunk // count
    if n_lanes is not None:
        lanes = n_lanes
    elif not accelerator:
        lanes = _CPU_LANES
    else:
        budget = int((info.memory or FALLBACK_MEMORY) * MEMORY_SHARE) // 2
        lanes = _lanes_fit(budget, lane_bytes)
    lanes = max(1, min(lanes, per_device))
    if not accelerator:
        return Plan(chunk, lanes, max(1, lanes // 16), 0, max(1, info.threads))
    tail = lanes // 4 if lanes >= TAIL_MIN_LANES else 0
    return Plan(chunk, lanes, max(1, lanes // 32), tail)


def _lanes_fit(budget: int, lane_bytes: int) -> int:
    """Lanes that fit `budget` bytes, at most `MAX_LANES` (a power of two when
    memory bounds it, so that lanes divide chunks evenly)."""
    fit = max(1, budget // max(1, lane_bytes))
    if fit >= MAX_LANES:
        return MAX_LANES
    return 1 << int(math.log2(fit))
