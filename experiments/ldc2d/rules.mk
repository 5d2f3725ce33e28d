# 2D lid-driven cavity, paper Figs. 6-7 (experiments/ldc2d/README.md). The runs (their metrics from
# analysis.py, re-evaluated without re-running) and the figures are the protocol's rules (Makefile:
# protocol_rules); what is this folder's own: each figure's runs are a group of their own (its dx; one
# stamp each, fig6_runs.done and fig7_runs.done, so `make fig6` runs only Fig. 6's), the paper's figure
# folders (results/<profile>/fig6/, fig7/; a copy, e.g. experiments/my_cavity, writes into
# results/<profile>/my_cavity/fig6/ ...), the table beside each figure, the animation of Fig. 6's TVF run
# (editing lab/animate.py re-renders only it) and the names fig6, fig7, fig6-runs, fig7-runs.
# Runs started in the background (background.sh) hold their folders' locks (lab.lock): a make asking
# for the same runs waits for them, then skips them.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_figs := $(if $(filter ldc2d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
GROUPS.$(_dir) := fig6 fig7
GROUP.$(_dir).fig6 := fig6
FIGDIR.$(_dir).fig6 := $(_figs)/fig6
EXTRA.$(_dir).fig6 := metrics.csv
GIF.$(_dir).fig6 := $(_figs)/fig6/fig6.gif
GROUP.$(_dir).fig7 := fig7
FIGDIR.$(_dir).fig7 := $(_figs)/fig7
EXTRA.$(_dir).fig7 := metrics.csv
DEPS.$(_dir).fig7 := $(_dir)/plot_fig6.py

ifeq ($(_name),ldc2d)
.PHONY: fig6 fig7 fig6-runs fig7-runs
fig6: $(addprefix $(RESULTS)/fig6/,fig6.png fig6.pdf metrics.csv fig6.gif)
fig7: $(addprefix $(RESULTS)/fig7/,fig7.png fig7.pdf metrics.csv)
fig6-runs: $(RESULTS)/ldc2d/fig6_runs.done
fig7-runs: $(RESULTS)/ldc2d/fig7_runs.done
endif
