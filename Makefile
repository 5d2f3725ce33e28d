# Reproduce JAX-SPH (Toshev et al. 2024) figures. `make fig5` is the main job, `make test` the tests.
# PROFILE=paper (default) runs the paper's sizes; PROFILE=smoke a small, fast version of each target.
PROFILE ?= paper
PY      := .venv/bin/python
VENV    := .venv/.stamp
RESULTS := results/$(PROFILE)
# Run steps always call their run script (FORCE): the script's own cache (sph.harness.runs) decides what
# re-runs, from fingerprints of the config and of exactly the code that can change the numbers, and
# notices damaged or incomplete outputs. A run step touches its stamp only when something changed,
# so the figures that depend on the stamp re-plot only then.
FORCE:


.PHONY: FORCE setup setup-lb test bench accuracy fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 stability clean help
.DEFAULT_GOAL := help

help:
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
	@echo "make sitl-cost [PROFILE=smoke]  Solver-in-the-Loop accuracy-cost plane: MSE_20 vs time per coarse step"
	@echo "make <folder>                   any experiments/<folder> with a tgv2d-style rules.mk (e.g. a copy of tgv2d)"
	@echo "make bench                      particle-steps per second, TGV 2D; cost of declared effects;\n                                 memory and time of gradients through 100-5000 steps"
	@echo "make bench-speed | bench-peer | scaling   TGV ms/step 2D/3D; against JAX-SPH 0.1.0; against particle count"
	@echo "make test                       test suite"
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
# test's time is XLA compilation, which uses one core
TEST_WORKERS ?= 2
test: $(VENV) .venv-lb/.stamp
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile tests

bench: $(VENV)
	$(PY) bench/bench_tgv.py
	$(PY) bench/bench_effects.py
	$(PY) bench/bench_guard.py
	$(PY) bench/bench_grad_memory.py

include $(wildcard experiments/*/rules.mk gradcheck/rules.mk inverse/rules.mk sitl/rules.mk bench/rules.mk)

clean:
	rm -rf results
