"""One simulation on several devices: spatial domain decomposition on JAX's SPMD (issue 40).

    decomposition   slabs along the longest axis, halo width, the refusals
    layout          a device's owned rows (`Shard`), capacities, host-side distribute / collect
    halo            halo build and the exchange plan of the pass list (ppermute)
    migration       particles to their new owner after the drift (ppermute)
    neighbors       the cell list over a device's rows, padding excluded
    driver          the sharded step, chunked rollout with re-allocation, differentiable rollout

Importing it starts nothing; the device count is whatever JAX sees (on CPU:
XLA_FLAGS=--xla_force_host_platform_device_count=D before jax is imported).

Several processes (hosts, or one process per GPU) run the same script; each calls, before anything
else touches JAX,

    jax.distributed.initialize(coordinator_address="host0:12345", num_processes=P, process_id=i)
    # CPU only: jax.config.update("jax_cpu_collectives_implementation", "gloo") before it

(under SLURM `jax.distributed.initialize()` takes all three from the SLURM_* variables: one task
per GPU, e.g. `srun -N 2 --ntasks-per-node=4 --gpus-per-task=1 python run.py`; not yet tried
here). `build_sharded(solver, D, processes=P)` then spans the devices of every process and refuses
a launch with another process count; every process holds the global initial state (host numpy),
`distribute` places each device's block, `collect` gathers the result on every process. Tested:
2 processes x 1 CPU device on localhost (tests/core/test_parallel.py).
"""
from .decomposition import Decomposition, decompose
from .driver import HaloOverflow, ShardedSolver, SlabSkipped, build_sharded
from .halo import ExchangePlan
from .layout import Capacities, Shard

__all__ = ["Decomposition", "decompose", "HaloOverflow", "ShardedSolver", "SlabSkipped", "build_sharded",
           "ExchangePlan", "Capacities", "Shard"]
