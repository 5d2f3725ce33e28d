# Benchmarks of the neighbour search and of the solver against JAX-SPH (what each measures: the
# docstrings of bench/bench_scaling.py, bench/bench_peer.py, bench/bench_neighbors.py, bench/bench_speed.py;
# bench/bench_ab.py and bench/bench_step_profile.py are run by hand). Included by the top-level Makefile,
# which defines PY and VENV. Always re-run (timings, not products).
.PHONY: scaling bench-peer bench-neighbors bench-speed

scaling: | $(VENV)
	nice $(PY) bench/bench_scaling.py --out results/bench

# JAX-SPH 0.1.0 lives in the LagrangeBench environment
bench-peer: | $(VENV) .venv-lb/.stamp
	nice .venv-lb/bin/python bench/bench_peer.py --out results/bench

bench-neighbors: | $(VENV)
	nice $(PY) bench/bench_neighbors.py

# time per step and peak memory of the TGV, 2D and 3D, SPH / TVF / Riemann (the README's Speed table)
bench-speed: | $(VENV)
	nice $(PY) bench/bench_speed.py
