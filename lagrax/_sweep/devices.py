"""Devices of a sweep: the mesh over the batch axis, and transfers."""

from typing import Any

import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np


def device_list(devices) -> list:
    """The devices a sweep runs on: `None` (all of `jax.devices()`), a count or a list."""
    if devices is None:
        return jax.devices()
    if isinstance(devices, (int, np.integer)):
        return jax.devices()[: int(devices)]
    return list(devices)


def mesh_of(devices) -> jax.sharding.Mesh | None:
    devices = device_list(devices)
    if len(devices) <= 1:
        return None
    return jax.sharding.Mesh(np.asarray(devices), ("batch",))


def to_device(x: np.ndarray, mesh) -> jax.Array:
    if mesh is None:
        return jnp.asarray(x)
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
    # each process fills the shards it owns: the same code runs single- and multi-host
    return jax.make_array_from_callback(x.shape, sharding, lambda idx: x[idx])


def to_host(tree: Any) -> Any:
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        tree = multihost_utils.process_allgather(tree, tiled=True)
    return jtu.tree_map(np.asarray, tree)
