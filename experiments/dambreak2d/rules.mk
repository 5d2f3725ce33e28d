# 2D dam break, paper Fig. 8 (experiments/dambreak2d/README.md).
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# The runs (one stamp for all columns) depend on the config, settings.py, run.py and the core; run.py
# itself skips runs whose outputs already match their inputs and resumes interrupted ones. The
# metrics depend on the runs, evaluate.py and the reference data; the figures on the metrics and
# their plot script, so editing evaluate.py only re-evaluates and editing the plot script only re-plots.
# fig8.gif animates the pressure of the Fig. 8 column (lab.animate), in the figure's colour range of
# p / (rho g H); editing lab/animate.py re-renders only it.
DB2D         := experiments/dambreak2d
DB2D_RUNS    := $(RESULTS)/dambreak2d/runs.done
DB2D_METRICS := $(RESULTS)/dambreak2d/metrics.csv
DB2D_REFS    := $(wildcard validation_refs/dambreak_*.csv)
FIG8_OUT     := $(addprefix $(RESULTS)/fig8/,fig8.png fig8.pdf validation.png validation.pdf metrics.csv)

.PHONY: fig8 dambreak2d

$(DB2D_RUNS): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(DB2D)/run.py --profile $(PROFILE) --results $(RESULTS)

# the evaluation and the figures run on every make through $(DELIVER) (lab.deliver): made
# again only when the current runs (the stamp), the scripts or their own files differ from what they were made from
$(DB2D_METRICS): OUTS := $(DB2D_METRICS)
$(DB2D_METRICS): $(DB2D_RUNS) $(DB2D)/evaluate.py $(DB2D_REFS) FORCE | $(VENV)
	$(DELIVER) $(PY) $(DB2D)/evaluate.py --profile $(PROFILE) --results $(RESULTS)

# the runs and their metrics only
dambreak2d: $(DB2D_METRICS)

fig8: $(FIG8_OUT) $(RESULTS)/fig8/fig8.gif
$(FIG8_OUT): OUTS := $(FIG8_OUT)
$(FIG8_OUT) &: $(DB2D_METRICS) $(DB2D_RUNS) $(DB2D)/plot_fig8.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DB2D)/plot_fig8.py --profile $(PROFILE) --results $(RESULTS)

$(RESULTS)/fig8/fig8.gif: OUTS := $(RESULTS)/fig8/fig8.gif
$(RESULTS)/fig8/fig8.gif: $(DB2D_RUNS) $(DB2D)/plot_fig8.py lab/animate.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DB2D)/plot_fig8.py --profile $(PROFILE) --results $(RESULTS) --gif $@
