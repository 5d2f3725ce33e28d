"""XLA's CPU flag for the pair sums (sph.xla_cpu): `import sph` leaves XLA_FLAGS alone; the
entry points' one call (`set_cpu_defaults`, made by `main_guard` / `profile_main`) sets it, keeps a
caller's own setting of it, and leaves XLA_FLAGS alone with SPH_XLA_DEFAULTS=0."""
import os
import subprocess
import sys

import jaxlib
import pytest

FLAG = "--xla_cpu_experimental_ynn_fusion_type"


def _flags_after(code, env_extra):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "SPH_XLA_DEFAULTS")}
    env.update(env_extra)
    code = f"import os; {code}; print(os.environ.get('XLA_FLAGS'))"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def test_import_sph_leaves_xla_flags_alone():
    assert _flags_after("import sph, lab.runs, lab.cli", {}) == "None"
    assert _flags_after("import sph", {"XLA_FLAGS": "--xla_foo=1"}) == "--xla_foo=1"


@pytest.mark.skipif(jaxlib.__version__ != "0.10.2", reason="the flag is set only for jaxlib 0.10.2")
def test_entry_points_set_the_flag_once_and_respect_opt_out():
    call = "from sph import xla_cpu; xla_cpu.set_cpu_defaults(); xla_cpu.set_cpu_defaults()"
    assert _flags_after(call, {}) == f"{FLAG}="
    assert _flags_after(call, {"XLA_FLAGS": "--xla_foo=1"}) == f"--xla_foo=1 {FLAG}="
    assert _flags_after(call, {"XLA_FLAGS": f"{FLAG}=reduce"}) == f"{FLAG}=reduce"
    assert _flags_after(call, {"SPH_XLA_DEFAULTS": "0"}) == "None"
    guard = "from lab.cli import main_guard; main_guard(lambda: None)"
    assert _flags_after(guard, {}) == f"{FLAG}="
