# Solver-in-the-Loop on RPF 2D, paper Fig. 3 and Table 1 (sitl/README.md).
# Included by the top-level Makefile, which defines PROFILE and RESULTS. .venv-lb has no editable install
# (its freeze check, docs/lagrangebench.md), so the sitl scripts put the repository root on sys.path.
# Everything runs in .venv-lb (our core on the same jax, plus LagrangeBench 0.2.0). The dataset depends on its config, its scripts and the core;
# each model's metrics on the dataset, the model/training/evaluation scripts; Table 1 and Fig. 3 only
# on the metrics / rollouts and their own script, so editing a plot or table script only re-plots.
# Training resumes from its last checkpoint when killed (sitl/train.py).
SITL        := sitl
SITL_PY     := .venv-lb/bin/python
SITL_VENV   := .venv-lb/.stamp
SITL_OUT    := $(RESULTS)/sitl
SITL_DATA   := $(SITL_OUT)/data/2D_RPF/generate.json
SITL_MODELS := solver gns sitl
SITL_METRICS := $(foreach m,$(SITL_MODELS),$(SITL_OUT)/metrics/$(m).json)
SITL_ENV    := WANDB_MODE=disabled
SITL_CORE   := $(shell find sph -name '*.py' 2>/dev/null)

.PHONY: fig3 table1 sitl-data

sitl-data: $(SITL_DATA)
$(SITL_DATA): $(SITL)/config.yaml $(SITL)/settings.py $(SITL)/generate.py $(SITL_CORE) | $(SITL_VENV)
	$(SITL_PY) $(SITL)/generate.py --profile $(PROFILE) --results $(RESULTS) --no-progress

$(SITL_OUT)/metrics/%.json: $(SITL_DATA) $(SITL)/model.py $(SITL)/common.py $(SITL)/train.py $(SITL)/evaluate.py | $(SITL_VENV)
	$(SITL_ENV) $(SITL_PY) $(SITL)/train.py --profile $(PROFILE) --results $(RESULTS) --model $*
	$(SITL_ENV) $(SITL_PY) $(SITL)/evaluate.py --profile $(PROFILE) --results $(RESULTS) --model $*

table1: $(RESULTS)/table1/table1.csv $(RESULTS)/table1/table1.md
$(RESULTS)/table1/table1.csv $(RESULTS)/table1/table1.md &: $(SITL_METRICS) $(SITL)/table1.py | $(SITL_VENV)
	$(SITL_PY) $(SITL)/table1.py --profile $(PROFILE) --results $(RESULTS)

fig3: $(RESULTS)/fig3/fig3.png $(RESULTS)/fig3/fig3.pdf
$(RESULTS)/fig3/fig3.png $(RESULTS)/fig3/fig3.pdf &: $(SITL_METRICS) $(SITL)/plot_fig3.py | $(SITL_VENV)
	$(SITL_PY) $(SITL)/plot_fig3.py --profile $(PROFILE) --results $(RESULTS)
