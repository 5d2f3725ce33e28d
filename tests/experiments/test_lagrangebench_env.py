"""LagrangeBench 0.2.0 lives in its own virtualenv, .venv-lb (make setup-lb).

test_lagrangebench_imports_in_venv_lb runs .venv-lb/bin/python in a
subprocess; it FAILS (does not skip) when .venv-lb is missing.
The lbcompat tests run in whatever interpreter runs pytest (core .venv is
fine): lbcompat imports only jax.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LB_VENV = ROOT / ".venv-lb"
LB_PYTHON = LB_VENV / "bin" / "python"
SETUP_HINT = "run `make setup-lb` (scripts/setup_lagrangebench.sh) to build it"


def _load_lbcompat():
    """Import <repo>/lbcompat.py without putting the repo root on the import path."""
    spec = importlib.util.spec_from_file_location("lbcompat", ROOT / "lbcompat.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# Runs inside .venv-lb. Prints one JSON line describing what it imported.
_PROBE = textwrap.dedent(
    """
    import json, warnings
    warnings.simplefilter("ignore", DeprecationWarning)  # jaxopt: unmaintained
    import lbcompat
    lb = lbcompat.import_lagrangebench()
    import jax, torch, wandb, ott, e3nn_jax, jax_sph
    import lagrangebench.models, lagrangebench.case_setup, lagrangebench.runner
    import jax_sph.io_state  # imports pyvista (+ vtk)
    import pyvista
    print(json.dumps({
        "version": lb.__version__,
        "file": lb.__file__,
        "models": sorted(n for n in ("GNS", "SEGNN", "EGNN", "PaiNN")
                         if isinstance(getattr(lagrangebench.models, n, None), type)),
        "case_builder": callable(lagrangebench.case_setup.case_builder),
        "top_level": sorted(n for n in ("Trainer", "infer", "case_builder",
                                        "H5Dataset", "TGV2D", "GNS")
                            if hasattr(lb, n)),
        "jax": jax.__version__,
        "torch": torch.__version__,
        "torch_cuda": torch.version.cuda,
        "e3nn_jax": e3nn_jax.__version__,
        "pyvista": pyvista.__version__,
    }))
    """
)


def test_lagrangebench_imports_in_venv_lb():
    if not LB_PYTHON.exists():
        pytest.fail(f"{LB_VENV} is missing: {SETUP_HINT}", pytrace=False)
    if not (LB_VENV / ".stamp").exists():
        pytest.fail(
            f"{LB_VENV} is incomplete (no .stamp; setup was interrupted or failed): {SETUP_HINT}",
            pytrace=False,
        )

    env = dict(os.environ, PYTHONPATH=str(ROOT), JAX_PLATFORMS="cpu", PYTHONNOUSERSITE="1")
    env.pop("VIRTUAL_ENV", None)
    proc = subprocess.run(
        [str(LB_PYTHON), "-c", _PROBE],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, (
        f"importing lagrangebench in {LB_VENV} failed (rc={proc.returncode}); "
        f"if the pins changed, {SETUP_HINT}\n--- stderr ---\n{proc.stderr[-4000:]}"
    )
    info = json.loads(proc.stdout.strip().splitlines()[-1])

    assert info["version"] == "0.2.0"
    # really the package installed in .venv-lb, not something on PYTHONPATH
    assert Path(info["file"]).resolve().is_relative_to(LB_VENV.resolve()), info["file"]
    assert info["models"] == ["EGNN", "GNS", "PaiNN", "SEGNN"]
    assert info["case_builder"] is True
    assert info["top_level"] == sorted(
        ["Trainer", "infer", "case_builder", "H5Dataset", "TGV2D", "GNS"]
    )
    assert info["torch"].endswith("+cpu") and info["torch_cuda"] is None, info
    assert info["e3nn_jax"] == "0.20.3"


@pytest.fixture
def lbcompat_applied():
    """Apply the aliases, and remove again whatever this test added."""
    lbcompat = _load_lbcompat()
    import jax

    added = lbcompat.apply_jax_aliases()
    try:
        yield lbcompat, jax
    finally:
        for name in added:
            delattr(jax, name)


def test_lbcompat_restores_tree_map(lbcompat_applied):
    lbcompat, jax = lbcompat_applied
    import jax.numpy as jnp
    import jax.tree_util as tu

    assert hasattr(jax, "tree_map")
    tree_a = {"x": jnp.arange(3.0), "y": (jnp.ones(2), 4.0), "z": None}
    tree_b = {"x": jnp.full(3, 2.0), "y": (jnp.zeros(2), 1.0), "z": None}

    got = jax.tree_map(lambda a, b: a * 10 + b, tree_a, tree_b)
    want = tu.tree_map(lambda a, b: a * 10 + b, tree_a, tree_b)
    assert tu.tree_structure(got) == tu.tree_structure(want)
    for g, w in zip(tu.tree_leaves(got), tu.tree_leaves(want)):
        assert jnp.array_equal(g, w)

    # same keyword behaviour (is_leaf), as lagrangebench/jax-sph may rely on it
    got_leaf = jax.tree_map(lambda t: len(t), tree_a, is_leaf=lambda t: isinstance(t, tuple))
    assert got_leaf["y"] == 2

    # the import-time use in jax_sph: `from jax import tree_map`
    from jax import tree_map  # noqa: F401

    # the other aliases round-trip like jax.tree_util
    leaves, treedef = jax.tree_flatten(tree_a)
    assert leaves == tu.tree_leaves(tree_a) == jax.tree_leaves(tree_a)
    assert tu.tree_structure(jax.tree_unflatten(treedef, leaves)) == tu.tree_structure(tree_a)


def test_lbcompat_aliases_are_documented_and_idempotent(lbcompat_applied):
    lbcompat, jax = lbcompat_applied
    import jax.tree_util as tu

    assert "tree_map" in lbcompat.JAX_ALIASES
    for name, (fn, why) in lbcompat.JAX_ALIASES.items():
        assert fn is getattr(tu, name), name  # aliases point at jax.tree_util
        assert why.strip(), f"alias {name} has no documented reason"
        assert getattr(jax, name) is not None
    assert lbcompat.apply_jax_aliases() == []  # second call adds nothing
