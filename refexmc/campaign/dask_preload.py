"""Dask worker preload of the LocalClusters ``refexmc run --scheduler local[:N]`` starts: each
worker process warms up as it starts (imports, numba's target, the kernels from the disk cache),
as a loky worker does in its initializer, instead of in its first task."""


def dask_setup(worker):
    """Called by distributed in each worker process before it takes tasks."""
    from refexmc.campaign import dask_backend

    dask_backend.warm_up_once()
