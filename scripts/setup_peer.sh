#!/usr/bin/env bash
# Build .venv-peer: JAX-SPH 0.1.0 in its own pinned environment (jax 0.4.29 / jaxlib 0.4.29, as its
# users install it), for `make bench-peer` only (Makefile rule .venv-peer/.stamp in bench/rules.mk;
# `make test` never builds it).
#
# Steps:
#   1. python3 -m venv .venv-peer
#   2. pip install -r environment-peer.txt minus jax-sph   (exact pins, resolved by pip: a missing or
#                                                            inconsistent pin fails here or in step 4)
#   3. pip install --no-deps --ignore-requires-python jax-sph==0.1.0
#      (it declares Requires-Python <=3.11, which rejects 3.11.7; its requirements are in step 2)
#   4. check: pip freeze == environment-peer.txt (plus pip, setuptools), pip check clean,
#      jax is 0.4.29 and JAX-SPH's solver modules import
#   5. touch .venv-peer/.stamp
#
# Idempotent: exits at once when the stamp is newer than environment-peer.txt and this script;
# otherwise .venv-peer is deleted and rebuilt from scratch, so it never drifts from the pins.
#
# Regenerating the pins (e.g. for another Python): in an empty venv run the two installs written in
# environment-peer.txt's header, then `pip freeze --all`, drop pip and setuptools, keep the comments.
#
# Options / environment:
#   --force          rebuild even if the stamp is fresh
#   PYTHON=...       interpreter for the venv (default: python3; must be 3.11)
#   PEER_VENV=...    venv location (default: <repo>/.venv-peer)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${PEER_VENV:-$ROOT/.venv-peer}"
PYTHON="${PYTHON:-python3}"
REQS="$ROOT/environment-peer.txt"
STAMP="$VENV/.stamp"
FORCE=0

log() { echo "setup_peer: $*"; }
die() { echo "setup_peer: ERROR: $*" >&2; exit 1; }

for arg in "$@"; do
  case "$arg" in
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,25p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) die "unknown argument: $arg (try --help)" ;;
  esac
done
[[ -f "$REQS" ]] || die "missing $REQS"

is_fresh() {
  [[ "$FORCE" == 0 && -f "$STAMP" && -x "$VENV/bin/python" \
     && "$STAMP" -nt "$REQS" && "$STAMP" -nt "${BASH_SOURCE[0]}" ]]
}
if is_fresh; then
  log "$VENV is up to date (stamp newer than environment-peer.txt and this script); nothing to do"
  exit 0
fi
# Serialise concurrent runs (make -j): lock on this script, re-check.
if command -v flock >/dev/null 2>&1; then
  exec 9<"${BASH_SOURCE[0]}"
  flock 9
  if is_fresh; then
    log "$VENV was built by a concurrent run; nothing to do"
    exit 0
  fi
fi
SECONDS=0

command -v "$PYTHON" >/dev/null 2>&1 || die "'$PYTHON' not found (set PYTHON=...)"
PYVER="$("$PYTHON" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])')"
[[ "$PYVER" == 3.11.* ]] || die "need Python 3.11 (the pins were resolved for it), got $PYVER from '$PYTHON'"

JAXSPH_PIN="$(sed -e 's/#.*//' -e 's/[[:space:]]//g' "$REQS" | grep -i -E '^jax[-_]sph==' || true)"
[[ -n "$JAXSPH_PIN" ]] || die "no 'jax-sph==...' pin in $REQS"
TMPD="$(mktemp -d)"
trap 'rm -rf "$TMPD"' EXIT
grep -v -i -E '^[[:space:]]*jax[-_]sph[[:space:]]*==' "$REQS" > "$TMPD/deps.txt"

if [[ -e "$VENV" ]]; then
  [[ -f "$VENV/pyvenv.cfg" ]] || die "$VENV exists but is not a virtualenv; refusing to delete it"
  log "removing stale/incomplete $VENV"
  rm -rf "$VENV"
fi
log "step 1/5: creating $VENV with $PYTHON ($PYVER)"
"$PYTHON" -m venv "$VENV"
echo '*' > "$VENV/.gitignore"
VPY="$VENV/bin/python"

# quiet pip; drops only the notes this machine's pip config prints for its local mirrors
pip_install() {
  "$VPY" -m pip install --quiet --no-input --disable-pip-version-check "$@" 2>&1 \
    | { grep -v -E "^WARNING: Location 'file://[^']*' is ignored: it is neither a file nor a directory\.$" || true; }
}

log "step 2/5: pip install -r environment-peer.txt (minus jax-sph)"
pip_install -r "$TMPD/deps.txt"
log "step 3/5: $JAXSPH_PIN (--no-deps --ignore-requires-python)"
pip_install --no-deps --ignore-requires-python "$JAXSPH_PIN"

log "step 4/5: checks"
"$VPY" -m pip freeze --all --disable-pip-version-check > "$TMPD/freeze.txt"
"$VPY" - "$REQS" "$TMPD/freeze.txt" <<'PY'
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

expected, installed = pins(sys.argv[1]), pins(sys.argv[2])
for name in ("pip", "setuptools"):
    installed.pop(name, None)
problems = [f"  {n}: pinned {expected.get(n) or '-'}, installed {installed.get(n) or '-'}"
            for n in sorted(set(expected) | set(installed)) if expected.get(n) != installed.get(n)]
if problems:
    sys.exit("setup_peer: ERROR: .venv-peer differs from environment-peer.txt (regenerate it, see "
             "scripts/setup_peer.sh):\n" + "\n".join(problems))
print(f"setup_peer: {len(installed)} packages, all match the pins")
PY
"$VPY" -m pip check --disable-pip-version-check || die "pip check found broken requirements (above)"
(cd "$TMPD" && JAX_PLATFORMS=cpu "$VPY" -c '
import jax, jaxlib
assert jax.__version__ == jaxlib.__version__ == "0.4.29", (jax.__version__, jaxlib.__version__)
import jax_sph.solver, jax_sph.integrator, jax_sph.partition, jax_sph.case_setup  # what bench/jaxsph_peer.py uses
from importlib.metadata import version
print("setup_peer: jax", jax.__version__, "jax-sph", version("jax-sph"), "from", jax_sph.solver.__file__)
')

log "step 5/5: stamp"
{
  echo "built $(date -u +%Y-%m-%dT%H:%M:%SZ) in ${SECONDS}s"
  echo "python $PYVER"
  echo "$JAXSPH_PIN jax==0.4.29 jaxlib==0.4.29"
} > "$STAMP"
log "done in ${SECONDS}s ($(du -sh "$VENV" | cut -f1)); stamp: $STAMP"
