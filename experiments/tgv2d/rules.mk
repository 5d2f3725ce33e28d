# 2D Taylor-Green vortex, paper Figs. 4-5 (experiments/tgv2d/README.md).
# Included by the top-level Makefile (PROFILE, PY, RESULTS, VENV, FORCE, DELIVER). Written for any
# folder name: a copy of this folder, experiments/my_study, is `make my_study` (runs + both figures into
# results/<profile>/my_study/), with no edit here. The run step always calls run.py, whose cache
# (lab.runs) re-runs exactly what changed and repairs damaged outputs; its stamp lists exactly
# the current runs (lab.stamp). Each figure rule runs on every make through $(DELIVER)
# (lab.deliver), which re-plots only when the current runs, the plot script or the figure's
# own files differ from what it was made from. fig4.gif animates the Fig. 4 run (fig4_method at the
# finest dx, lab.animate); editing lab/animate.py re-renders only it.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_runs := $(RESULTS)/$(_name)/runs.done
_figs := $(if $(filter tgv2d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
_fig4 := $(_figs)/fig4/fig4.png $(_figs)/fig4/fig4.pdf
_fig5 := $(_figs)/fig5/fig5.png $(_figs)/fig5/fig5.pdf $(_figs)/fig5/metrics.csv

$(_runs): DIR := $(_dir)
$(_runs): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(DIR)/run.py --profile $(PROFILE) --results $(RESULTS)

$(_fig4): DIR := $(_dir)
$(_fig4): OUTS := $(_fig4)
$(_fig4) &: $(_runs) $(_dir)/plot_fig4.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DIR)/plot_fig4.py --profile $(PROFILE) --results $(RESULTS) --out $(dir $@)

$(_figs)/fig4/fig4.gif: DIR := $(_dir)
$(_figs)/fig4/fig4.gif: OUTS := $(_figs)/fig4/fig4.gif
$(_figs)/fig4/fig4.gif: $(_runs) $(_dir)/plot_fig4.py lab/animate.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DIR)/plot_fig4.py --profile $(PROFILE) --results $(RESULTS) --gif $@

$(_fig5): DIR := $(_dir)
$(_fig5): OUTS := $(_fig5)
$(_fig5) &: $(_runs) $(_dir)/plot_fig5.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DIR)/plot_fig5.py --profile $(PROFILE) --results $(RESULTS) --out $(dir $@)

.PHONY: $(_name)
$(_name): $(_figs)/fig4/fig4.png $(_figs)/fig4/fig4.gif $(_figs)/fig5/fig5.png

ifeq ($(_name),tgv2d)
fig4: $(RESULTS)/fig4/fig4.png $(RESULTS)/fig4/fig4.pdf $(RESULTS)/fig4/fig4.gif
fig5: $(RESULTS)/fig5/fig5.png $(RESULTS)/fig5/fig5.pdf $(RESULTS)/fig5/metrics.csv
endif
