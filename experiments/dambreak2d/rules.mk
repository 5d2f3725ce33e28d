# 2D dam break, paper Fig. 8 (experiments/dambreak2d/README.md). The runs (their metrics from
# analysis.py, re-evaluated on every make without re-running) and the figure are the protocol's rules
# (Makefile: protocol_rules); what is this folder's own: the paper's figure folder (results/<profile>/fig8/;
# a copy, e.g. experiments/my_dam, writes into results/<profile>/my_dam/fig8/), the files beside the
# figure, the animation of the Fig. 8 column's pressure (editing lab/animate.py re-renders only it)
# and the name fig8.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_figs := $(if $(filter dambreak2d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
FIGDIR.$(_dir).fig8 := $(_figs)/fig8
EXTRA.$(_dir).fig8 := validation.png validation.pdf metrics.csv
GIF.$(_dir).fig8 := $(_figs)/fig8/fig8.gif

ifeq ($(_name),dambreak2d)
.PHONY: fig8
fig8: $(addprefix $(RESULTS)/fig8/,fig8.png fig8.pdf validation.png validation.pdf metrics.csv fig8.gif)
endif
