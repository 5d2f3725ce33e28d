# The accuracy-cost atlas (experiments/accuracy/README.md). Included by the top-level Makefile.
# The TGV sweep step always calls run.py (its cache re-runs only what changed); the atlas is rebuilt
# from every run record of the results folder whenever the sweep's outputs changed or atlas.py did,
# and on every call when the figures' runs may have changed (it is cheap: it only reads records).
ACCURACY     := experiments/accuracy

.PHONY: accuracy
$(RESULTS)/accuracy/tgv.done: FORCE | $(VENV)
	$(PY) -m sph.harness.stamp $@ $(RESULTS)/accuracy/tgv -- $(PY) $(ACCURACY)/run.py --profile $(PROFILE) --results $(RESULTS)

accuracy: $(RESULTS)/accuracy/tgv.done | $(VENV)
	$(PY) $(ACCURACY)/atlas.py --profile $(PROFILE) --results $(RESULTS)
