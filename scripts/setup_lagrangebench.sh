#!/usr/bin/env bash
# Build the separate LagrangeBench virtualenv .venv-lb (called by `make setup-lb`).
#
# Layers, in order (see docs/lagrangebench.md for the why):
#   1. python3 -m venv .venv-lb
#   2. pip install -r environment.txt                       (the core pins)
#   3. pip install torch==<pin>                             (local CPU wheel, alone, first)
#   4. pip install -r environment-lagrangebench.txt         (minus the two below;
#                                                            overrides e3nn-jax)
#   5. pip install --no-deps --ignore-requires-python lagrangebench==0.2.0 jax-sph==0.1.0
#   6. pip install --no-deps -e .                           (this project, editable, as in .venv:
#                                                            sph, sitl, lbcompat import from anywhere)
#   7. check: pip freeze (editable installs aside) == environment.txt +
#      environment-lagrangebench.txt, this project is the one editable install,
#      pip check shows only the known-ignored pins, `import lagrangebench` works
#   8. touch .venv-lb/.stamp
#
# Idempotent: exits at once when .venv-lb/.stamp is newer than both env files
# (and than this script, matching the Makefile rule's prerequisites).
# Otherwise (no stamp = new or half-built env, or stale stamp) .venv-lb is
# deleted and rebuilt from scratch, so it never drifts from the pin files.
#
# Options / environment:
#   --force        rebuild even if the stamp is fresh
#   PYTHON=...     interpreter for the venv (default: python3; must be 3.11)
#   LB_VENV=...    venv location (default: <repo>/.venv-lb)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${LB_VENV:-$ROOT/.venv-lb}"
PYTHON="${PYTHON:-python3}"
CORE_REQS="$ROOT/environment.txt"
LB_REQS="$ROOT/environment-lagrangebench.txt"
PYPROJECT="$ROOT/pyproject.toml"
STAMP="$VENV/.stamp"
FORCE=0

log() { echo "setup_lagrangebench: $*"; }
die() { echo "setup_lagrangebench: ERROR: $*" >&2; exit 1; }

for arg in "$@"; do
  case "$arg" in
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,23p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) die "unknown argument: $arg (try --help)" ;;
  esac
done

for f in "$CORE_REQS" "$LB_REQS"; do
  [[ -f "$f" ]] || die "missing $f"
done

# Same inputs as the Makefile rule for .venv-lb/.stamp: both pin files, the
# project's pyproject.toml (its editable install) and this script (a changed
# install procedure also means a rebuild).
is_fresh() {
  [[ "$FORCE" == 0 && -f "$STAMP" && -x "$VENV/bin/python" \
     && "$STAMP" -nt "$CORE_REQS" && "$STAMP" -nt "$LB_REQS" \
     && "$STAMP" -nt "$PYPROJECT" && "$STAMP" -nt "${BASH_SOURCE[0]}" ]]
}

if is_fresh; then
  log "$VENV is up to date (stamp newer than environment*.txt, pyproject.toml and this script); nothing to do"
  exit 0
fi

# Serialise concurrent runs (e.g. `make -j`): lock on this script, re-check.
if command -v flock >/dev/null 2>&1; then
  exec 9<"${BASH_SOURCE[0]}"
  flock 9
  if is_fresh; then
    log "$VENV was built by a concurrent run; nothing to do"
    exit 0
  fi
fi

SECONDS=0

# --- interpreter ------------------------------------------------------------
command -v "$PYTHON" >/dev/null 2>&1 || die "'$PYTHON' not found (set PYTHON=...)"
PYVER="$("$PYTHON" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])')"
[[ "$PYVER" == 3.11.* ]] \
  || die "need Python 3.11 (environment.txt and the cp311 torch CPU wheel), got $PYVER from '$PYTHON'"

# --- read the pins ------------------------------------------------------------
# pin_of NAME: the "NAME==VERSION" line of environment-lagrangebench.txt.
pin_of() {
  local line
  line="$(sed -e 's/#.*//' -e 's/[[:space:]]//g' "$LB_REQS" | grep -i -E "^$1==" || true)"
  [[ -n "$line" ]] || die "no '$1==...' pin in $LB_REQS"
  echo "$line"
}
TORCH_PIN="$(pin_of torch)"
LB_PIN="$(pin_of lagrangebench)"
JAXSPH_PIN="$(pin_of jax-sph)"

TMPD="$(mktemp -d)"
trap 'rm -rf "$TMPD"' EXIT
# Everything except lagrangebench / jax-sph, which need --no-deps (step 5).
grep -v -i -E '^[[:space:]]*(lagrangebench|jax-sph|jax_sph)[[:space:]]*==' "$LB_REQS" > "$TMPD/extras.txt"

# --- fresh venv -----------------------------------------------------------------
if [[ -e "$VENV" ]]; then
  [[ -f "$VENV/pyvenv.cfg" ]] || die "$VENV exists but is not a virtualenv; refusing to delete it"
  log "removing stale/incomplete $VENV"
  rm -rf "$VENV"
fi
log "step 1/8: creating $VENV with $PYTHON ($PYVER)"
"$PYTHON" -m venv "$VENV"
# Keep the env out of git without touching the repo's .gitignore.
echo '*' > "$VENV/.gitignore"

VPY="$VENV/bin/python"

# pip install, quiet; drops only the harmless per-package notes this machine's
# pip config prints for its local mirrors ("Location 'file://...' is ignored").
# pipefail keeps pip's exit status.
pip_install() {
  "$VPY" -m pip install --quiet --no-input --disable-pip-version-check "$@" 2>&1 \
    | { grep -v -E "^WARNING: Location 'file://[^']*' is ignored: it is neither a file nor a directory\.$" || true; }
}

log "step 2/8: core pins: pip install -r environment.txt"
pip_install -r "$CORE_REQS"

log "step 3/8: $TORCH_PIN (CPU build, local wheel)"
if ! pip_install "$TORCH_PIN" -c "$TMPD/extras.txt"; then
  die "could not install $TORCH_PIN. It is the CPU wheel from pip's find-links (/opt/wheels here); pip must not fall back to the CUDA build from the index."
fi

log "step 4/8: extras: pip install -r environment-lagrangebench.txt (minus lagrangebench, jax-sph)"
pip_install -r "$TMPD/extras.txt"

log "step 5/8: $LB_PIN $JAXSPH_PIN (--no-deps --ignore-requires-python)"
pip_install --no-deps --ignore-requires-python "$LB_PIN" "$JAXSPH_PIN"

log "step 6/8: this project, editable: pip install --no-deps -e $ROOT"
pip_install --no-deps -e "$ROOT"

# --- checks -------------------------------------------------------------------
log "step 7/8: checking installed set against environment.txt + environment-lagrangebench.txt"
# the editable install of this project is not a pin: left out here, checked below
"$VPY" -m pip freeze --all --exclude-editable --disable-pip-version-check > "$TMPD/freeze.txt"
"$VPY" - "$CORE_REQS" "$LB_REQS" "$TMPD/freeze.txt" <<'PY'
import re, sys

def canon(name):
    return re.sub(r"[-_.]+", "-", name).lower()

def pins(path):
    out = {}
    for line in open(path):
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, ver = line.partition("==")
            out[canon(name)] = ver.strip()
    return out

expected = pins(sys.argv[1])
expected.update(pins(sys.argv[2]))          # lagrangebench pins override core ones
installed = pins(sys.argv[3])
installed.pop("pip", None)
problems = []
for name in sorted(set(expected) | set(installed)):
    want, have = expected.get(name), installed.get(name)
    if want != have:
        problems.append(f"  {name}: pinned {want or '-'}, installed {have or '-'}")
if problems:
    sys.exit("setup_lagrangebench: ERROR: .venv-lb differs from the pin files "
             "(regenerate environment-lagrangebench.txt, see docs/lagrangebench.md):\n"
             + "\n".join(problems))
print(f"setup_lagrangebench: {len(installed)} packages, all match the pins")
PY
"$VPY" -m pip list --editable --format=freeze --disable-pip-version-check > "$TMPD/editable.txt"
[[ "$(sed -e 's/==.*//' "$TMPD/editable.txt" | tr '[:upper:]_' '[:lower:]-')" == "jax-sph-repro" ]] \
  || die "expected this project (jax-sph-repro) as the only editable install, got: $(tr '\n' ' ' < "$TMPD/editable.txt")"
(cd / && "$VPY" - "$ROOT" <<'PY'
import importlib.util, os, sys
for name in ("sph", "sitl", "experiments", "lbcompat"):
    spec = importlib.util.find_spec(name)
    where = (spec.origin or "") if spec and spec.origin else " ".join(spec.submodule_search_locations or []) if spec else ""
    if not where.startswith(sys.argv[1] + os.sep):
        sys.exit(f"setup_lagrangebench: ERROR: {name} is not found in {sys.argv[1]} from outside it (found: {where or 'nothing'})")
PY
)
log "editable install: $(cat "$TMPD/editable.txt") from $ROOT"

# lagrangebench / jax-sph metadata still asks for jax 0.4.29 etc. (that is why
# they go in with --no-deps); any OTHER broken requirement is an error.
"$VPY" -m pip check --disable-pip-version-check > "$TMPD/check.txt" 2>&1 || true
unexpected="$(grep -v -E \
    -e '^(lagrangebench|jax-sph) [0-9.]+ has requirement (jax\[cpu\]|jaxlib|optax|torch)==' \
    -e '^No broken requirements' "$TMPD/check.txt" || true)"
if [[ -n "$unexpected" ]]; then
  echo "$unexpected" >&2
  die "pip check found unexpected broken requirements (above)"
fi
log "pip check: only the ignored jax/jaxlib/optax/torch pins of lagrangebench/jax-sph differ"

log "smoke test: import lagrangebench via lbcompat"
(cd "$ROOT" && JAX_PLATFORMS=cpu "$VPY" -W ignore::DeprecationWarning -c \
  'import lbcompat; lb = lbcompat.import_lagrangebench(); print("setup_lagrangebench: lagrangebench", lb.__version__, "from", lb.__file__)')

{
  echo "built $(date -u +%Y-%m-%dT%H:%M:%SZ) in ${SECONDS}s"
  echo "python $PYVER"
  echo "$LB_PIN $JAXSPH_PIN $TORCH_PIN"
} > "$STAMP"
log "done in ${SECONDS}s ($(du -sh "$VENV" | cut -f1)); stamp: $STAMP"
