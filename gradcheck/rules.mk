# Gradient check, paper Fig. 1 (gradcheck/README.md): `make fig1`, `make grad-growth` [PROFILE=smoke].
# The runs (study.py: a check per case and precision, group fig1; a gradient norm per case and rollout
# length, group growth; each computed and cached by the harness, lab.experiment `compute`) and the figures
# (plot_fig1.py, plot_grad_norm_vs_steps.py) are the protocol's rules (Makefile: protocol_rules); each
# group has its own run step and stamp, so fig1 does not wait for grad-growth (minutes: reverse mode
# through up to 1000 steps, one compilation per rollout length). What is this folder's own: its groups,
# the figures' folder (<results>/fig1), the tables the plots write beside them and the target names.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
GROUPS.$(_dir) := fig1 growth
FIGDIR.$(_dir).fig1 := $(RESULTS)/fig1
EXTRA.$(_dir).fig1 := metrics.csv sweep.csv
GROUP.$(_dir).fig1 := fig1
FIGDIR.$(_dir).grad_norm_vs_steps := $(RESULTS)/fig1
EXTRA.$(_dir).grad_norm_vs_steps := grad_norm_vs_steps.csv
GROUP.$(_dir).grad_norm_vs_steps := growth

ifeq ($(notdir $(_dir)),gradcheck)
.PHONY: fig1 grad-growth
fig1: $(RESULTS)/fig1/fig1.png
grad-growth: $(RESULTS)/fig1/grad_norm_vs_steps.png
endif
