# Solver-in-the-Loop on RPF 2D, paper Fig. 3 and Table 1 (experiments/sitl/README.md): `make table1`,
# `make fig3`, `make sitl` [PROFILE=smoke]. The runs (study.py: each model trained and evaluated, group
# table1; its rollouts over Fig. 3's horizon, group fig3) and the figure (plot_fig3.py) are the protocol's
# rules (Makefile: protocol_rules), run in LagrangeBench's environment once the dataset is current; the
# dataset, Table 1 itself, the study and the cost plane are the library's rules (sitl/rules.mk).
# What is this folder's own: its interpreter and what its runs need, its groups, the figure's folder and
# the tables its plot writes beside it, the target name.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
PYTHON.$(_dir) = $(SITL_ENV) $(SITL_PY)
NEEDS.$(_dir) = $(SITL_DATA) $(SITL_VENV)
GROUPS.$(_dir) := table1 fig3
FIGDIR.$(_dir).fig3 = $(RESULTS)/fig3
EXTRA.$(_dir).fig3 := fig3_mse.png mse_steps.csv mse_steps.md
GROUP.$(_dir).fig3 := fig3

ifeq ($(notdir $(_dir)),sitl)
.PHONY: fig3
fig3: $(RESULTS)/fig3/fig3.png
endif
