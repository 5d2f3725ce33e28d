"""A jitted function timed apart from its execution: compiled (`jit(...).lower(...).compile()`, which
fills the same cache the calls use) before its first call with each new argument signature, so that
compilation is measured apart from the steps even when a neighbour re-allocation changes the shapes
mid-run (`sph.simulate`'s `compile_s` and `wall_s`)."""
import time

import jax
import numpy as np


class CompiledChunk:
    """A jitted chunk that compiles (timed) before its first call with each new argument signature,
    so compilation is measured apart from execution even when `advance` re-allocates mid-chunk."""

    def __init__(self, jitted):
        self.jitted = jitted
        self.guard = getattr(jitted, "guard", None)  # make_chunk's step guard, for `advance`
        self.seen = set()
        self.compile_s = 0.0

    @staticmethod
    def _signature(args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x).__name__))) for x in leaves)

    def compile(self, *args):
        sig = self._signature(args)
        if sig not in self.seen:
            t0 = time.perf_counter()
            self.jitted.lower(*args).compile()
            self.compile_s += time.perf_counter() - t0
            self.seen.add(sig)

    def __call__(self, *args):
        self.compile(*args)
        return self.jitted(*args)
