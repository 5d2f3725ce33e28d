# Stability suite (experiments/stability/README.md): `make stability [PROFILE=smoke]`.
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# The table depends on the config, the scripts, the relaxation (sph.relax, used by the long TGV case) and
# the core, so editing any of these re-runs run.py; run.py itself re-runs only the cases whose
# inputs (their simulation settings, cases.py, settings.py, sph/) changed
# and reuses the others' stored results, so editing a criterion or run.py only re-evaluates the table.
# A failing case is a row of the table, never a failed make. STABILITY_FLAGS=--ignore-code-changes
# reuses cases run with an older sph/ (same settings).
STABILITY     := experiments/stability
STABILITY_OUT := $(RESULTS)/stability

.PHONY: stability
stability: $(STABILITY_OUT)/stability.csv $(STABILITY_OUT)/stability.md

$(STABILITY_OUT)/stability.csv $(STABILITY_OUT)/stability.md &: FORCE | $(VENV)
	$(PY) $(STABILITY)/run.py --profile $(PROFILE) --results $(RESULTS) $(STABILITY_FLAGS)
