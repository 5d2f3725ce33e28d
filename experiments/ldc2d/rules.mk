# 2D lid-driven cavity, paper Figs. 6-7 (experiments/ldc2d/README.md).
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# Each figure has its own runs (fig6: figures.fig6's dx, fig7: figures.fig7's), one stamp per figure.
# The runs depend on the config, settings.py, run.py and the core, so editing any of these re-runs
# run.py, which itself skips runs whose trajectories already match their inputs and resumes
# interrupted ones; LDC2D_FLAGS passes extra options to run.py.
# The figures depend on the runs, analysis.py and plot.py: editing those (or the
# `analysis` settings) re-evaluates and re-plots without re-running. fig6.gif animates the fig6 run of
# LDC2D_GIF_METHOD (lab.animate); editing lab/animate.py re-renders only it.
LDC2D     := experiments/ldc2d

.PHONY: fig6 fig7 fig6-runs fig7-runs

# refuse to start a figure's runs while background.sh processes of that figure are still writing them
ldc2d_no_background = @for f in $(RESULTS)/ldc2d/logs/*_$(1).pid; do \
	  [ -f "$$f" ] && kill -0 "$$(cat $$f)" 2>/dev/null && { echo "ldc2d: $(1) runs are still going in the \
	  background (pid $$(cat $$f), log $${f%.pid}.log); wait for them to finish"; exit 1; }; done; true

$(RESULTS)/ldc2d/fig6_runs.done: FORCE | $(VENV)
	$(call ldc2d_no_background,fig6)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(LDC2D)/run.py --profile $(PROFILE) --results $(RESULTS) --fig fig6 $(LDC2D_FLAGS)

$(RESULTS)/ldc2d/fig7_runs.done: FORCE | $(VENV)
	$(call ldc2d_no_background,fig7)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(LDC2D)/run.py --profile $(PROFILE) --results $(RESULTS) --fig fig7 $(LDC2D_FLAGS)

fig6-runs: $(RESULTS)/ldc2d/fig6_runs.done
fig7-runs: $(RESULTS)/ldc2d/fig7_runs.done

# Each figure rule runs on every make through $(DELIVER) (lab.deliver): re-plotted only when
# the figure's current runs (its stamp), the scripts or the figure's own files differ from what it was made from.
FIG6_OUT := $(addprefix $(RESULTS)/fig6/,fig6.png fig6.pdf metrics.csv)
FIG7_OUT := $(addprefix $(RESULTS)/fig7/,fig7.png fig7.pdf metrics.csv)

fig6: $(FIG6_OUT) $(RESULTS)/fig6/fig6.gif
$(FIG6_OUT): OUTS := $(FIG6_OUT)
$(FIG6_OUT) &: $(RESULTS)/ldc2d/fig6_runs.done $(LDC2D)/config.yaml $(LDC2D)/analysis.py $(LDC2D)/plot.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(LDC2D)/plot.py --fig fig6 --profile $(PROFILE) --results $(RESULTS)

fig7: $(FIG7_OUT)
$(FIG7_OUT): OUTS := $(FIG7_OUT)
$(FIG7_OUT) &: $(RESULTS)/ldc2d/fig7_runs.done $(LDC2D)/config.yaml $(LDC2D)/analysis.py $(LDC2D)/plot.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(LDC2D)/plot.py --fig fig7 --profile $(PROFILE) --results $(RESULTS)

LDC2D_GIF_METHOD ?= tvf
$(RESULTS)/fig6/fig6.gif: OUTS := $(RESULTS)/fig6/fig6.gif
$(RESULTS)/fig6/fig6.gif: $(RESULTS)/ldc2d/fig6_runs.done $(LDC2D)/plot.py lab/animate.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(LDC2D)/plot.py --fig fig6 --profile $(PROFILE) --results $(RESULTS) --gif $@ --method $(LDC2D_GIF_METHOD)
