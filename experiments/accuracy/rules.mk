# The accuracy-cost atlas (experiments/accuracy/README.md). Included by the top-level Makefile.
# The TGV sweep step always calls run.py (its cache re-runs only what changed); the atlas gathers the
# run records of exactly the current runs (those the experiments' run stamps list) and runs on every
# make through $(DELIVER) (lab.deliver): rebuilt when a stamp, a record it read, atlas.py or
# one of its own files differs from what it was made from.
ACCURACY     := experiments/accuracy

.PHONY: accuracy
$(RESULTS)/accuracy/tgv.done: FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(RESULTS)/accuracy/tgv -- $(PY) $(ACCURACY)/run.py --profile $(PROFILE) --results $(RESULTS)

ATLAS_OUT := $(addprefix $(RESULTS)/accuracy/,runs.csv accuracy.png accuracy.pdf convergence.png accuracy.md)
accuracy: $(ATLAS_OUT)
$(ATLAS_OUT): OUTS := $(ATLAS_OUT)
$(ATLAS_OUT) &: $(RESULTS)/accuracy/tgv.done $(ACCURACY)/atlas.py $(ACCURACY)/config.yaml lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(ACCURACY)/atlas.py --profile $(PROFILE) --results $(RESULTS)
