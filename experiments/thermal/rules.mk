# Thermal studies (experiments/thermal/README.md): heat-operator validation and paper Fig. 10.
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# Each study has its own stamp; `make fig10` builds the channel figure and the heat-operator
# validation (`make heat-validation` alone builds the latter). The
# runs depend on the config, settings/run scripts and the core; run.py itself skips runs whose
# outputs already match their inputs. The figures depend on the runs and their plot script only.
THERMAL       := experiments/thermal
THERMAL_DEPS  := $(THERMAL)/config.yaml $(THERMAL)/settings.py $(THERMAL)/run.py $(CORE)
THERMAL_SINE  := $(RESULTS)/thermal/sine.done
THERMAL_CHAN  := $(RESULTS)/thermal/channel.done

.PHONY: heat-validation fig10

$(THERMAL_SINE): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(THERMAL)/run.py --task sine --profile $(PROFILE) --results $(RESULTS)

$(THERMAL_CHAN): FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(THERMAL)/run.py --task channel --profile $(PROFILE) --results $(RESULTS)

# the figures run on every make through $(DELIVER) (lab.deliver): re-plotted only when the
# current runs (the stamps), the scripts or the figures' own files differ from what they were made from
HEAT_OUT  := $(addprefix $(RESULTS)/heat_validation/,heat_validation.png heat_validation.pdf metrics.csv)
FIG10_OUT := $(addprefix $(RESULTS)/fig10/,fig10.png fig10.pdf fig10_series.png metrics.csv series.csv)

heat-validation: $(HEAT_OUT)
$(HEAT_OUT): OUTS := $(HEAT_OUT)
$(HEAT_OUT) &: $(THERMAL_SINE) $(THERMAL)/plot_heat_validation.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(THERMAL)/plot_heat_validation.py --profile $(PROFILE) --results $(RESULTS)

fig10: $(FIG10_OUT) heat-validation
$(FIG10_OUT): OUTS := $(FIG10_OUT)
$(FIG10_OUT) &: $(THERMAL_CHAN) $(THERMAL)/plot_fig10.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(THERMAL)/plot_fig10.py --profile $(PROFILE) --results $(RESULTS)
