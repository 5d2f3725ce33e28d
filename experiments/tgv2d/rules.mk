# 2D Taylor-Green vortex, paper Figs. 4-5 (experiments/tgv2d/README.md).
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, CORE and exports PYTHONPATH.
# The runs (one stamp for all of them) depend on the config, the run/relax scripts and the core, so
# editing any of these re-runs; run.py itself skips runs whose outputs already match their inputs
# and resumes interrupted ones. The figures depend on the runs and their plot script only, so editing
# a plot script only re-plots.
TGV2D      := experiments/tgv2d
TGV2D_RUNS := $(RESULTS)/tgv2d/runs.done

$(TGV2D_RUNS): $(TGV2D)/config.yaml $(TGV2D)/settings.py $(TGV2D)/relax.py $(TGV2D)/run.py $(CORE) | $(VENV)
	$(PY) $(TGV2D)/run.py --profile $(PROFILE) --results $(RESULTS)
	@touch $@

fig4: $(RESULTS)/fig4/fig4.png $(RESULTS)/fig4/fig4.pdf
$(RESULTS)/fig4/fig4.png $(RESULTS)/fig4/fig4.pdf &: $(TGV2D_RUNS) $(TGV2D)/plot_fig4.py
	$(PY) $(TGV2D)/plot_fig4.py --profile $(PROFILE) --results $(RESULTS)

fig5: $(RESULTS)/fig5/fig5.png $(RESULTS)/fig5/fig5.pdf $(RESULTS)/fig5/metrics.csv
$(RESULTS)/fig5/fig5.png $(RESULTS)/fig5/fig5.pdf $(RESULTS)/fig5/metrics.csv &: $(TGV2D_RUNS) $(TGV2D)/plot_fig5.py
	$(PY) $(TGV2D)/plot_fig5.py --profile $(PROFILE) --results $(RESULTS)
