# 3D Taylor-Green vortex, paper Fig. 9 (experiments/tgv3d/README.md).
# Included by the top-level Makefile (PROFILE, PY, RESULTS, VENV, FORCE). Written for any folder
# name: a copy of this folder, experiments/my_study, is `make my_study` (runs + figure into
# results/<profile>/my_study/), with no edit here. The run step always calls run.py, whose cache
# (lab.runs) re-runs exactly what changed and repairs damaged outputs; its stamp changes only when an
# output did, so the figure re-plots only then, or when its plot script or the analysis changes.
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_runs := $(RESULTS)/$(_name)/runs.done
_figs := $(if $(filter tgv3d,$(_name)),$(RESULTS),$(RESULTS)/$(_name))

$(_runs): DIR := $(_dir)
$(_runs): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(DIR)/run.py --profile $(PROFILE) --results $(RESULTS)

_fig9 := $(_figs)/fig9/fig9.png $(_figs)/fig9/fig9.pdf $(_figs)/fig9/metrics.csv
$(_fig9): DIR := $(_dir)
$(_fig9): OUTS := $(_fig9)
$(_fig9) &: $(_runs) $(_dir)/plot_fig9.py $(_dir)/analysis.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(DIR)/plot_fig9.py --profile $(PROFILE) --results $(RESULTS) --out $(dir $@)

.PHONY: $(_name)
$(_name): $(_figs)/fig9/fig9.png

ifeq ($(_name),tgv3d)
fig9: $(RESULTS)/fig9/fig9.png $(RESULTS)/fig9/fig9.pdf $(RESULTS)/fig9/metrics.csv
endif
