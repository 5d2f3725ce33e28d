# Gradient check, paper Fig. 1 (gradcheck/README.md): `make fig1`, `make grad-growth` [PROFILE=smoke].
# Included by the top-level Makefile, which defines PROFILE, PY, RESULTS, VENV and FORCE. Run steps
# always call their run script (its cache decides what re-runs, see lab.runs) through lab.stamp, whose
# stamp changes only when an output changed.
# The computations (one stamp for the AD/FD check, one for the rollout-length sweep) depend on the
# config, settings.py, run.py and the core, so editing any of these recomputes; run.py itself reuses
# checks and growth rows whose inputs are unchanged. The figures depend on their computation and the
# plot script only, so editing plot.py only re-plots. fig1 does not wait for grad-growth (minutes:
# reverse mode through up to 1000 steps, one compilation per rollout length).
GRADCHECK        := gradcheck
GRADCHECK_OUT    := $(RESULTS)/gradcheck

.PHONY: fig1 grad-growth

$(GRADCHECK_OUT)/check.done: FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(GRADCHECK)/run.py --profile $(PROFILE) --results $(RESULTS) --part check

$(GRADCHECK_OUT)/growth.done: FORCE | $(VENV)
	$(PY) -m lab.stamp $@ $(dir $@) -- $(PY) $(GRADCHECK)/run.py --profile $(PROFILE) --results $(RESULTS) --part growth

# the figures run on every make through $(DELIVER) (lab.deliver): re-plotted only when the
# current results (the stamps), the script or the figures' own files differ from what they were made from
FIG1_OUT   := $(addprefix $(RESULTS)/fig1/,fig1.png fig1.pdf metrics.csv)
GROWTH_OUT := $(addprefix $(RESULTS)/fig1/,grad_norm_vs_steps.png grad_norm_vs_steps.csv)

fig1: $(FIG1_OUT)
$(FIG1_OUT): OUTS := $(FIG1_OUT)
$(FIG1_OUT) &: $(GRADCHECK_OUT)/check.done $(GRADCHECK)/plot.py lab/figures.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(GRADCHECK)/plot.py --profile $(PROFILE) --results $(RESULTS) --what fig1

grad-growth: $(GROWTH_OUT)
$(GROWTH_OUT): OUTS := $(GROWTH_OUT)
$(GROWTH_OUT) &: $(GRADCHECK_OUT)/growth.done $(GRADCHECK)/plot.py FORCE | $(VENV)
	$(DELIVER) $(PY) $(GRADCHECK)/plot.py --profile $(PROFILE) --results $(RESULTS) --what growth
