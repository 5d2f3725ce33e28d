# Thermal studies (experiments/thermal/README.md): heat-operator validation and paper Fig. 10.
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see sph.harness.runs) through sph.harness.stamp, whose
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
	$(PY) -m sph.harness.stamp $@ $(dir $@) -- $(PY) $(THERMAL)/run.py --task sine --profile $(PROFILE) --results $(RESULTS)

$(THERMAL_CHAN): FORCE | $(VENV)
	$(PY) -m sph.harness.stamp $@ $(dir $@) -- $(PY) $(THERMAL)/run.py --task channel --profile $(PROFILE) --results $(RESULTS)

heat-validation: $(RESULTS)/heat_validation/heat_validation.png $(RESULTS)/heat_validation/metrics.csv
$(RESULTS)/heat_validation/heat_validation.png $(RESULTS)/heat_validation/heat_validation.pdf $(RESULTS)/heat_validation/metrics.csv &: $(THERMAL_SINE) $(THERMAL)/plot_heat_validation.py
	$(PY) $(THERMAL)/plot_heat_validation.py --profile $(PROFILE) --results $(RESULTS)

fig10: $(RESULTS)/fig10/fig10.png $(RESULTS)/fig10/fig10.pdf $(RESULTS)/fig10/metrics.csv heat-validation
$(RESULTS)/fig10/fig10.png $(RESULTS)/fig10/fig10.pdf $(RESULTS)/fig10/fig10_series.png $(RESULTS)/fig10/metrics.csv $(RESULTS)/fig10/series.csv &: $(THERMAL_CHAN) $(THERMAL)/plot_fig10.py
	$(PY) $(THERMAL)/plot_fig10.py --profile $(PROFILE) --results $(RESULTS)
