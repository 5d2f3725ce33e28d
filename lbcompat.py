"""Compatibility shims for running LagrangeBench 0.2.0 on current JAX.

LagrangeBench 0.2.0 (and its neighbour-list dependency jax-sph 0.1.0) were
written against jax 0.4.29 and use the top-level ``jax.tree_*`` aliases.
Those aliases were deprecated in jax 0.4.26 in favour of ``jax.tree_util.*`` /
``jax.tree.*`` and have since been removed; none of them exist in jax 0.10.2
(the version pinned in environment.txt). This module puts them back, pointing
at the real ``jax.tree_util`` functions, *before* lagrangebench is imported.

This is the ONE place where such aliases live. Usage::

    from lbcompat import import_lagrangebench
    lagrangebench = import_lagrangebench()

or, to import only jax_sph / a submodule, call ``apply_jax_aliases()`` first.

Importing this module has no side effects: it only imports jax and patches
nothing until ``apply_jax_aliases()`` / ``import_lagrangebench()`` is called,
so it is safe to import from the core ``.venv`` too (it does not import
lagrangebench, torch, wandb, ...). ``import_lagrangebench()`` needs the
separate ``.venv-lb`` environment (``make setup-lb``, i.e.
``scripts/setup_lagrangebench.sh``). See docs/lagrangebench.md.

Not shimmed (not needed by ``import lagrangebench`` nor by training /
evaluation): e3nn-jax 0.20.3's developer helpers ``e3nn_jax.utils.jit_code``
and ``optimize_jaxpr`` use ``jax.lib.xla_bridge`` / ``xla_call_p``, which are
gone from current jax; lagrangebench never calls them.
"""

from __future__ import annotations

import importlib
from types import ModuleType

import jax
import jax.tree_util

# name on ``jax`` -> (replacement, why it is needed).
# Only aliases that lagrangebench / jax-sph / ott-jax actually use are listed;
# each comment names the call sites (versions: lagrangebench 0.2.0,
# jax-sph 0.1.0, ott-jax 0.4.5).
JAX_ALIASES: dict[str, tuple[object, str]] = {
    # IMPORT TIME: jax_sph/jax_md/partition.py does
    # ``from jax import ..., tree_map, ...`` and lagrangebench/case_setup/case.py
    # imports that module, so without this ``import lagrangebench`` fails.
    # Run time: lagrangebench utils.py, train/trainer.py, evaluate/rollout.py,
    # case_setup/features.py call ``jax.tree_map(...)``.
    "tree_map": (
        jax.tree_util.tree_map,
        "jax_sph.jax_md.partition imports it (import time); lagrangebench "
        "trainer/rollout/features/utils call jax.tree_map",
    ),
    # Run time: lagrangebench/utils.py save_pytree (checkpointing) and
    # get_num_params call ``jax.tree_leaves``.
    "tree_leaves": (
        jax.tree_util.tree_leaves,
        "lagrangebench.utils.save_pytree / get_num_params",
    ),
    # Run time: lagrangebench/utils.py load_pytree (checkpoint loading), and
    # the flatten function that ott/utils.py ``register_pytree_node`` installs
    # on ott's dataclasses (SinkhornDivergenceOutput, Momentum, ...):
    # ``jax.tree_flatten(dataclasses.asdict(obj))``, hit whenever such an
    # object is flattened (e.g. returned through jit/vmap).
    "tree_flatten": (
        jax.tree_util.tree_flatten,
        "lagrangebench.utils.load_pytree and ott.utils.register_pytree_node",
    ),
    # Run time: lagrangebench/utils.py load_pytree rebuilds the checkpoint
    # pytree with ``jax.tree_unflatten``.
    "tree_unflatten": (
        jax.tree_util.tree_unflatten,
        "lagrangebench.utils.load_pytree",
    ),
}


def apply_jax_aliases() -> list[str]:
    """Patch the removed ``jax.tree_*`` aliases onto ``jax``.

    Idempotent; never overrides an attribute jax already provides (so on an
    old jax the real functions are kept). Returns the names it added.
    """
    added = []
    for name, (fn, _why) in JAX_ALIASES.items():
        if not hasattr(jax, name):
            setattr(jax, name, fn)
            added.append(name)
    return added


def import_lagrangebench() -> ModuleType:
    """Apply the jax aliases, then import and return ``lagrangebench``."""
    apply_jax_aliases()
    return importlib.import_module("lagrangebench")


__all__ = ["JAX_ALIASES", "apply_jax_aliases", "import_lagrangebench"]
