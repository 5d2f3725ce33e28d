# Thermal studies (experiments/thermal/README.md): heat-operator validation and paper Fig. 10. The runs
# (both kinds, one stamp) and both figures are the protocol's rules (Makefile: protocol_rules); what is
# this folder's own: the figure folders (results/<profile>/heat_validation/, fig10/; a copy of this
# folder, e.g. experiments/my_heat, writes into results/<profile>/my_heat/...), the files the plots
# write beside their figures, and the names heat-validation and fig10 (which makes both figures).
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
_name := $(notdir $(_dir))
_figs := $(if $(filter thermal,$(_name)),$(RESULTS),$(RESULTS)/$(_name))
FIGDIR.$(_dir).heat_validation := $(_figs)/heat_validation
EXTRA.$(_dir).heat_validation := metrics.csv
FIGDIR.$(_dir).fig10 := $(_figs)/fig10
EXTRA.$(_dir).fig10 := fig10_series.png metrics.csv series.csv

ifeq ($(_name),thermal)
.PHONY: heat-validation fig10
heat-validation: $(addprefix $(RESULTS)/heat_validation/,heat_validation.png heat_validation.pdf metrics.csv)
fig10: $(addprefix $(RESULTS)/fig10/,fig10.png fig10.pdf fig10_series.png metrics.csv series.csv) heat-validation
endif
