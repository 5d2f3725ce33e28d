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
# The atlas reads every experiment's run stamp: the other targets asked for on the same command line
# (`make -j2 fig9 accuracy`) finish first (order-only: asked alone, it runs no experiment)
ATLAS_AFTER := $(filter-out accuracy report snapshot readme-tables $(ATLAS_OUT),$(MAKECMDGOALS))
accuracy: $(ATLAS_OUT)
$(ATLAS_OUT): OUTS := $(ATLAS_OUT)
$(ATLAS_OUT) &: $(RESULTS)/accuracy/tgv.done $(ACCURACY)/atlas.py $(ACCURACY)/config.yaml lab/figures.py FORCE | $(VENV) $(ATLAS_AFTER)
	$(DELIVER) $(PY) $(ACCURACY)/atlas.py --profile $(PROFILE) --results $(RESULTS)
