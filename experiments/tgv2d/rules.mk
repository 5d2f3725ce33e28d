# 2D Taylor-Green vortex, paper Figs. 4-5 (experiments/tgv2d/README.md). The runs and both figures are
# the protocol's rules (Makefile: protocol_rules); what is this folder's own: the paper's figure folders
# (results/<profile>/fig4/, fig5/; a copy of this folder, e.g. experiments/my_study, writes into
# results/<profile>/my_study/fig4/ and fig5/), the table's copy beside Fig. 5, the animation of Fig. 4's
# run (fig4_method at the finest dx; editing lab/animate.py re-renders only it) and the names fig4, fig5.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_figs := $(if $(filter tgv2d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
FIGDIR.$(_dir).fig4 := $(_figs)/fig4
GIF.$(_dir).fig4 := $(_figs)/fig4/fig4.gif
FIGDIR.$(_dir).fig5 := $(_figs)/fig5
EXTRA.$(_dir).fig5 := metrics.csv

ifeq ($(_name),tgv2d)
.PHONY: fig4 fig5
fig4: $(RESULTS)/fig4/fig4.png $(RESULTS)/fig4/fig4.pdf $(RESULTS)/fig4/fig4.gif
fig5: $(RESULTS)/fig5/fig5.png $(RESULTS)/fig5/fig5.pdf $(RESULTS)/fig5/metrics.csv
endif
