# 3D Taylor-Green vortex, paper Fig. 9 (experiments/tgv3d/README.md). The runs (their metrics from
# analysis.py, re-evaluated without re-running) and the figure are the protocol's rules (Makefile:
# protocol_rules); what is this folder's own: the paper's figure folder (results/<profile>/fig9/; a
# copy, e.g. experiments/my_study, writes into results/<profile>/my_study/fig9/), the table's copy
# beside the figure and the name fig9.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_figs := $(if $(filter tgv3d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
FIGDIR.$(_dir).fig9 := $(_figs)/fig9
EXTRA.$(_dir).fig9 := metrics.csv

ifeq ($(_name),tgv3d)
.PHONY: fig9
fig9: $(RESULTS)/fig9/fig9.png $(RESULTS)/fig9/fig9.pdf $(RESULTS)/fig9/metrics.csv
endif
