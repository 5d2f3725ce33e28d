# Inverse problem, paper Fig. 2 (inverse/README.md): `make fig2`, `make inverse` [PROFILE=smoke].
# The optimizations (study.py: one run per case, start and optimizer, each computed and cached by the
# harness, lab.experiment `compute`; the table summary.csv) and the figure (plot_fig2.py) are the
# protocol's rules (Makefile: protocol_rules): `make inverse` is the folder's target (its runs and its
# figure, re-plotted only when a run changed). What is this folder's own: the figure's folder
# (<results>/fig2), the tables the plot writes beside it and the target name.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
FIGDIR.$(_dir).fig2 := $(RESULTS)/fig2
EXTRA.$(_dir).fig2 := metrics.csv summary.csv

ifeq ($(notdir $(_dir)),inverse)
.PHONY: fig2
fig2: $(RESULTS)/fig2/fig2.png
endif
