"""`import sph` sets XLA's CPU flag for the pair sums (sph.xla_cpu) in XLA_FLAGS, keeps a caller's own
setting of it, and leaves XLA_FLAGS alone with SPH_XLA_DEFAULTS=0."""
import os
import subprocess
import sys

import jaxlib
import pytest

FLAG = "--xla_cpu_experimental_ynn_fusion_type"


def _flags_after_import(env_extra):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "SPH_XLA_DEFAULTS")}
    env.update(env_extra)
    code = "import os, sph; print(os.environ.get('XLA_FLAGS', ''))"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


@pytest.mark.skipif(jaxlib.__version__ != "0.10.2", reason="the flag is set only for jaxlib 0.10.2")
def test_import_sets_the_flag_once_and_respects_opt_out():
    assert _flags_after_import({}) == f"{FLAG}="
    assert _flags_after_import({"XLA_FLAGS": "--xla_foo=1"}) == f"--xla_foo=1 {FLAG}="
    assert _flags_after_import({"XLA_FLAGS": f"{FLAG}=reduce"}) == f"{FLAG}=reduce"
    assert _flags_after_import({"SPH_XLA_DEFAULTS": "0"}) == ""
