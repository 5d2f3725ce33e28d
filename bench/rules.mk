# Benchmarks of the neighbour search and of the solver against JAX-SPH (what each measures: the
# docstrings of bench/bench_scaling.py, bench/bench_peer.py, bench/bench_neighbors.py, bench/bench_speed.py;
# bench/bench_ab.py and bench/bench_step_profile.py are run by hand). Included by the top-level Makefile,
# which defines PY and VENV. Always re-run (timings, not products).
.PHONY: scaling bench-peer bench-neighbors bench-speed bench-devices bench-suite

scaling: | $(VENV)
	nice $(PY) bench/bench_scaling.py --out results/bench

# JAX-SPH 0.1.0 in its own pinned environment (.venv-peer: jax 0.4.29, built here on first use, never by
# `make test`) against ours in .venv, one process each: the headline rows; beside them both codes in
# one process on the project's jax (.venv-lb, where JAX-SPH 0.1.0 is installed for LagrangeBench)
bench-peer: | $(VENV) .venv-lb/.stamp .venv-peer/.stamp
	nice $(PY) -m bench.bench_peer --out results/bench

.venv-peer/.stamp: environment-peer.txt scripts/setup_peer.sh
	bash scripts/setup_peer.sh

bench-neighbors: | $(VENV)
	nice $(PY) bench/bench_neighbors.py

# time per step and peak memory of the TGV, 2D and 3D, SPH / TVF / Riemann (the README's Speed table)
bench-speed: | $(VENV)
	nice $(PY) bench/bench_speed.py

# the sharded step (sph.parallel, issue 40): strong and weak scaling over D devices (forced host devices
# on a CPU: they share its cores), memory per device, halo particles and exchange bytes per step
DEVICES_LIST ?= 1 2 4
bench-devices: | $(VENV)
	nice $(PY) bench/bench_devices.py --devices $(DEVICES_LIST)

# where the test suite's time goes (bench/bench_suite.py): per test file, CPU in the pytest workers and
# in the processes they start, and JAX's tracing / XLA compile time, from a fresh compilation cache
bench-suite: | $(VENV) .venv-lb/.stamp
	$(PY) bench/bench_suite.py --log results/bench/suite_cost.jsonl
