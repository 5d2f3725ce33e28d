# Inverse problem, paper Fig. 2 (inverse/README.md).
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# The optimizations (one stamp for all) depend on the config, the scripts they use and the core;
# run.py itself skips when its outputs were made from the same inputs. The figure depends on the
# optimization results and its plot script only, so editing plot.py only re-plots.
INVERSE      := inverse
INVERSE_RUNS := $(RESULTS)/inverse/runs.done
FIG2_OUT     := $(addprefix $(RESULTS)/fig2/,fig2.png fig2.pdf metrics.csv summary.csv)

.PHONY: fig2 inverse

$(INVERSE_RUNS): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(INVERSE)/run.py --profile $(PROFILE) --results $(RESULTS)

# the optimizations and their metrics only
inverse: $(INVERSE_RUNS)

fig2: $(FIG2_OUT)
$(FIG2_OUT): OUTS := $(FIG2_OUT)
$(FIG2_OUT) &: $(INVERSE_RUNS) $(INVERSE)/plot.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(INVERSE)/plot.py --profile $(PROFILE) --results $(RESULTS)
