# Reproduce JAX-SPH (Toshev et al. 2024) figures. `make fig5` is the main job, `make test` the tests.
# PROFILE=paper (default) runs the paper's sizes; PROFILE=smoke a small, fast version of each target.
PROFILE ?= paper
PY      := .venv/bin/python
VENV    := .venv/.stamp
RESULTS := results/$(PROFILE)
ifneq ($(words $(RESULTS)),1)
$(error RESULTS='$(RESULTS)' holds a space: give a results folder without spaces)
endif
# Run steps always call their run script (FORCE): the script's own cache (lab.runs) decides what
# re-runs, from fingerprints of the config and of exactly the code that can change the numbers, and
# notices damaged or incomplete outputs. A run step touches its stamp only when something changed,
# so the figures that depend on the stamp re-plot only then.
FORCE:

# Deliverables (figures, metrics tables, the atlas) are verified on every make, by one mechanism
# (lab.deliver): each deliverable rule is FORCE'd and its recipe is `$(DELIVER) <command>`,
# with its outputs in the target-specific OUTS. DELIVER re-makes the outputs only when the manifest
# written beside them (every input's digest: the run stamps, which list exactly the current runs, the
# scripts, the files the script read; every output's digest) differs from now: a method or dx removed
# from a profile, a re-run, a truncated metrics.csv or a missing figure. Otherwise one line, "up to date".
DELIVER = $(PY) -m lab.deliver $(OUTS) --from $(filter-out FORCE,$^) --


.PHONY: FORCE setup setup-lb test tests bench accuracy fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 stability clean clean-expensive help
.PHONY: all all-targets all-sitl report snapshot restore readme-tables
.DEFAULT_GOAL := help

help:
	@echo "make all [PROFILE=smoke]        every paper target, the stability matrix, the atlas and the report (resumable, -j2 safe)"
	@echo "make report [PROFILE=smoke]     results/<profile>/report/index.html + report.md: each figure beside the paper"
	@echo "make snapshot [PROFILE=paper]   copy the finished report, metrics and records into docs/results/<profile>/ (<= 10 MB; a clean tree, or DIRTY=1 to mark it)"
	@echo "make restore [PROFILE=paper]    seed results/<profile>/ from the committed snapshot (a fresh clone keeps its targets)"
	@echo "make readme-tables              README and docs/ tables from the committed snapshot (between <!-- table:NAME --> markers)"
	@echo "make fig1 [PROFILE=smoke]       gradient check: AD vs finite differences, TGV and cavity (paper Fig. 1)"
	@echo "make grad-growth                gradient norm against rollout length (1 ... 1000 steps)"
	@echo "make fig2 [PROFILE=smoke]       inverse problem: recover initial positions (paper Fig. 2)"
	@echo "make fig4 fig5 [PROFILE=smoke]  2D Taylor-Green vortex (paper Figs. 4-5)"
	@echo "make fig6 fig7 [PROFILE=smoke]  lid-driven cavity vs Ghia et al. 1982 (dx 0.02 / 0.01)"
	@echo "make fig8 [PROFILE=smoke]       Riemann-SPH dam break vs Buchner 2002, Martin & Moyce 1952"
	@echo "make fig9 [PROFILE=smoke]       3D Taylor-Green vortex, Re 100, vs JAX-Fluids (paper Fig. 9)"
	@echo "make fig10 [PROFILE=smoke]      heated channel (paper Fig. 10) + heat-validation"
	@echo "make heat-validation            heat operator vs the analytical decay of a sine, dx 0.05-0.01"
	@echo "make stability [PROFILE=smoke]  matrix of hard cases -> results/<profile>/stability/"
	@echo "make accuracy [PROFILE=smoke]   accuracy-cost atlas: error vs wall time of every run record + a TGV sweep"
	@echo "make sitl-data [PROFILE=smoke]  the RPF 2D dataset of Table 1 alone (our solver, LagrangeBench's layout)"
	@echo "make sitl-cost [PROFILE=smoke]  Solver-in-the-Loop accuracy-cost plane: MSE_20 vs time per coarse step"
	@echo "make sitl-study [PROFILE=smoke] when SitL beats the solver alone: noise, coarsening, seeds, equal cost"
	@echo "make sitl-divergence [PROFILE=smoke] where the coarse solver and SitL rollouts break, step by step"
	@echo "make droplet [PROFILE=smoke]    surface tension: a 2D droplet at rest against Laplace's law (beyond the paper)"
	@echo "make <folder>                   any experiments/<folder> with a study.py (the protocol, lab.experiment): its runs and figures"
	@echo "  ... DEVICES=N                    (Figs. 4-10 and <folder>) each run's steps on N devices (a CPU is split into N)"
	@echo "make bench                      particle-steps per second, TGV 2D; cost of declared effects;\n                                 memory and time of gradients through 100-5000 steps"
	@echo "make bench-speed | bench-peer | scaling   TGV ms/step 2D/3D; against JAX-SPH 0.1.0; against particle count"
	@echo "make test                       test suite"
	@echo "make clean [PROFILE=smoke] [FORCE=1]  list results/<profile> with sizes; delete it only with FORCE=1"
	@echo "make clean-expensive PROFILE=paper FORCE=1  the same for the paper / cpu profiles (hours of runs, trained models)"
	@echo "make setup / setup-lb           core environment / LagrangeBench environment"

setup: $(VENV)
$(VENV): environment.txt pyproject.toml
	python3 -m venv .venv
	.venv/bin/pip install --quiet --upgrade pip
	.venv/bin/pip install --quiet -r environment.txt
	.venv/bin/pip install --quiet --no-deps -e .
	touch $@

setup-lb: .venv-lb/.stamp
.venv-lb/.stamp: environment.txt environment-lagrangebench.txt pyproject.toml scripts/setup_lagrangebench.sh
	bash scripts/setup_lagrangebench.sh

# the tests run in TEST_WORKERS processes (pytest-xdist), a test file per worker at a time: most of a
# test's time is XLA compilation, which uses one core (tests/conftest.py: the longest files first, and
# JAX's persistent compilation cache shared by the test processes); the 25 slowest tests are listed
TEST_WORKERS ?= 2
test: $(VENV) .venv-lb/.stamp
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=25 tests

bench: $(VENV)
	$(PY) bench/bench_tgv.py
	$(PY) bench/bench_effects.py
	$(PY) bench/bench_guard.py
	$(PY) bench/bench_grad_memory.py

# --- the whole reproduction (report/README.md) ---------------------------------------------------
# `make all` prints each target's expected wall time (report.plan: measured by earlier runs, else
# docs/time_estimates.yaml), then builds the paper targets in dependency order, the stability
# matrix, then the atlas (it gathers every run record) and the report. Every run step is resumable
# (its script's cache), and `make -j2 all` runs independent targets side by side: a run folder is
# locked while written (lab.lock). Table 1 / Fig. 3 need a GPU in the paper profile: without
# one they are made in the `cpu` profile (SITL_PROFILE), which the report shows labelled as such.
PAPER_TARGETS := fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10
SITL_TARGETS  := table1 fig3
HAS_GPU       := $(shell nvidia-smi -L >/dev/null 2>&1 && echo yes)
ifeq ($(PROFILE)$(HAS_GPU),paper)
SITL_PROFILE  ?= cpu
else
SITL_PROFILE  ?= $(PROFILE)
endif
README_PROFILE ?= paper

all: | $(VENV)
	+@$(PY) -m report.plan --profile $(PROFILE) --results $(RESULTS) --sitl-profile $(SITL_PROFILE) \
	  $(PAPER_TARGETS) $(SITL_TARGETS) stability accuracy
	+@$(MAKE) --no-print-directory all-targets

all-targets: $(PAPER_TARGETS) all-sitl stability
	+$(MAKE) --no-print-directory accuracy
	+$(MAKE) --no-print-directory report

all-sitl:
	+$(MAKE) --no-print-directory $(SITL_TARGETS) PROFILE=$(SITL_PROFILE) RESULTS=$(dir $(RESULTS))$(SITL_PROFILE)

# the report reads every target's outputs: the targets asked beside it (`make -j2 fig5 report`) finish first
report: | $(VENV) $(filter-out report snapshot restore readme-tables clean clean-expensive,$(MAKECMDGOALS))
	$(PY) -m report.build --profile $(PROFILE) --results $(RESULTS)

snapshot: | $(VENV)
	$(PY) -m report.snapshot --profile $(PROFILE) --results $(RESULTS) --out docs/results/$(PROFILE) $(if $(DROP),--drop) $(if $(DIRTY),--allow-dirty)

restore: | $(VENV)
	$(PY) -m report.restore --profile $(PROFILE)

readme-tables: | $(VENV)
	$(PY) -m report.readme_tables --snapshot docs/results/$(README_PROFILE)

# the folders of the protocol (lab.experiment): every experiments/*/study.py, gradcheck and inverse, or those given (a copy elsewhere,
# PROTOCOL_DIRS=/tmp/my_study); each folder's rules.mk, where it has one, says what is its own (below)
PROTOCOL_DIRS ?= $(patsubst %/study.py,%,$(wildcard experiments/*/study.py gradcheck/study.py inverse/study.py))
include $(sort $(wildcard experiments/*/rules.mk gradcheck/rules.mk inverse/rules.mk sitl/rules.mk bench/rules.mk \
                          $(addsuffix /rules.mk,$(PROTOCOL_DIRS))))

# --- experiment folders of the protocol (lab.experiment): config.yaml + study.py + plot_<name>.py
# One rule set for every such folder, whatever its name (a copy is `make <copy>`): the run step calls the
# harness, whose cache re-runs exactly what changed, and stamps the current runs; each plot_<name>.py makes
# <name>.{png,pdf} through $(DELIVER), re-plotting only when the runs, the script or the folder's analysis.py
# change. What a folder's
# rules.mk may say of its plot <name> (d: the folder as PROTOCOL_DIRS lists it, e.g. experiments/tgv2d):
#   FIGDIR.<d>.<name>  the figure's folder (default $(RESULTS)/<folder name>), e.g. a paper figure's $(RESULTS)/fig5
#   EXTRA.<d>.<name>   other files the plot script writes there (e.g. metrics.csv, a copy of the table)
#   GIF.<d>.<name>     an animation the plot script writes with --gif (plot_main's `gif`; lab.animate)
#   DEPS.<d>.<name>    other inputs of the figure (e.g. a reference data file)
#   GROUP.<d>.<name>   the group of runs the figure shows, one of GROUPS.<d> (the groups of the folder's runs,
#                      lab.experiment --group): each group has its own run step and stamp <group>_runs.done,
#                      so making one figure runs only its runs (default: every run, runs.done)
#   PYTHON.<d>         the command that runs the folder's steps and plots (default $(PY)), e.g. experiments/sitl's
#                      LagrangeBench environment
#   NEEDS.<d>          what every run step of the folder needs first besides its environment (e.g. a dataset made
#                      by a library rule, or the environment's stamp)
# DEVICES=N: every protocol run's steps on N devices (sph.parallel; a CPU-only host is split into N XLA devices),
# equal to one device's numbers to round-off, so no run re-keys; the run's record states its device count
PROTOCOL_DEVICES = $(if $(DEVICES),--devices $(DEVICES))
protocol_py = $(or $(PYTHON.$(1)),$(PY))
protocol_figdir = $(or $(FIGDIR.$(1).$(2)),$(RESULTS)/$(notdir $(1)))
protocol_outs = $(addprefix $(call protocol_figdir,$(1),$(2))/,$(2).png $(2).pdf $(EXTRA.$(1).$(2)))
protocol_stamp = $(RESULTS)/$(notdir $(1))/$(if $(GROUP.$(1).$(2)),$(GROUP.$(1).$(2))_)runs.done
define newline


endef
define protocol_rules
$(RESULTS)/$(notdir $(1))/runs.done: $(NEEDS.$(1)) FORCE | $(VENV)
	$(call protocol_py,$(1)) -m lab.stamp $$@ $$(dir $$@) -- $(call protocol_py,$(1)) -m lab.experiment $(1) --profile $$(PROFILE) --results $$(RESULTS) $$(PROTOCOL_DEVICES)
$(foreach g,$(GROUPS.$(1)),$(call protocol_group,$(1),$(g))$(newline))
$(foreach p,$(wildcard $(1)/plot_*.py),$(call protocol_plot,$(1),$(p),$(patsubst plot_%.py,%,$(notdir $(p))))$(newline))
.PHONY: $(notdir $(1))
$(notdir $(1)): $(foreach p,$(wildcard $(1)/plot_*.py),$(call protocol_figdir,$(1),$(patsubst plot_%.py,%,$(notdir $(p))))/$(patsubst plot_%.py,%,$(notdir $(p))).png $(GIF.$(1).$(patsubst plot_%.py,%,$(notdir $(p)))))
endef
define protocol_group
$(RESULTS)/$(notdir $(1))/$(2)_runs.done: $(NEEDS.$(1)) FORCE | $(VENV)
	$(call protocol_py,$(1)) -m lab.stamp $$@ $$(dir $$@) -- $(call protocol_py,$(1)) -m lab.experiment $(1) --group $(2) --profile $$(PROFILE) --results $$(RESULTS) $$(PROTOCOL_DEVICES)
endef
define protocol_plot
$(call protocol_outs,$(1),$(3)): OUTS := $(call protocol_outs,$(1),$(3))
$(call protocol_outs,$(1),$(3)) &: $(call protocol_stamp,$(1),$(3)) $(2) $(wildcard $(1)/analysis.py) $(DEPS.$(1).$(3)) lab/figures.py FORCE | $(VENV)
	$$(DELIVER) $(call protocol_py,$(1)) $(2) --profile $$(PROFILE) --results $$(RESULTS) --out $(call protocol_figdir,$(1),$(3))
$(if $(GIF.$(1).$(3)),$(call protocol_gif,$(1),$(2),$(GIF.$(1).$(3)),$(call protocol_stamp,$(1),$(3))))
endef
define protocol_gif
$(3): OUTS := $(3)
$(3): $(4) $(2) lab/animate.py FORCE | $(VENV)
	$$(DELIVER) $(call protocol_py,$(1)) $(2) --profile $$(PROFILE) --results $$(RESULTS) --gif $$@
endef
$(foreach d,$(PROTOCOL_DIRS),$(eval $(call protocol_rules,$(d))))

# clean: results/<profile> only, listed with sizes, deleted only with FORCE=1; without PROFILE= on the
# command line the smoke profile; the paper and cpu profiles (hours of runs, trained models) only through
# clean-expensive (scripts/clean.py)
CLEAN_PROFILE := $(if $(filter command line environment,$(origin PROFILE)),$(PROFILE),smoke)
clean:
	@python3 scripts/clean.py $(CLEAN_PROFILE) $(if $(FORCE),--force)
clean-expensive:
	@python3 scripts/clean.py $(PROFILE) --expensive $(if $(FORCE),--force)

# a target make has no rule for is an error, not "Nothing to be done" (make tests: a folder of that name)
tests:
	@echo "make: no target 'tests': did you mean 'make test'? (make help lists the targets)" >&2; exit 2
.DEFAULT:
	@echo "make: no rule to make '$@' (make help lists the targets)" >&2; exit 2
