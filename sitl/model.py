"""Solver-in-the-Loop (Um et al. 2020) for temporally coarsened SPH, as a haiku module that
LagrangeBench's Trainer and `infer` accept (Toshev et al. 2024, Sec. 5, App. B, Listing 1).

One coarse step of Delta t = dt * write_every (LagrangeBench's frame interval) from the input
positions r^{-1}, r^0 (features["abs_pos"], after LagrangeBench's noise):

    u = d(r^0, r^{-1}) / Delta t                      (the velocity LagrangeBench sees, physical units;
                                                       model.start "consistent" adds (Delta t / 2)(1 - 1/W) a)
    repeat L times, delta t = Delta t / L:
        rho  = summation density at r;  p = Tait(rho) with the data's background pressure
        a    = our SPH momentum (standard, viscous) + the RPF body force      (sph.build_solver; the
                                                       authors' uniform one with model.solver_force)
             + GNN(r, u, f, [a, i]) * sigma_a / Delta t^2  (the corrector: LagrangeBench's GNS, its
                                                       normalised output scaled to physical units; f the
                                                       data's per-particle force, LagrangeBench's feature;
                                                       with model.extra_inputs also the solver's a and the
                                                       substep index i; skipped entirely when
                                                       correction=False: "solver only")
        u   += delta t a;   r = shift(r, delta t u)   (symplectic Euler)
        SPH and graph neighbour lists updated at r; an overflow sets state['overflow'] and the output NaN
    output {"acc": (d(r^L, r^0) - d(r^0, r^{-1}) - mu_a) / sigma_a}

so LagrangeBench's integrator (v' = v + sigma_a acc + mu_a, r' = r^0 + v') lands exactly on r^L. The
authors' version divided by Delta t^2 once more here (harmless only because mu_a ~ 0), ran its
solver with p_bg = 0 against data made with 0.05, and never checked its lists for overflow; all three
are fixed here. Only the corrector's weights are parameters; gradients flow through every SPH substep.
"""
import dataclasses
import warnings
from dataclasses import dataclass

import haiku as hk
import jax
import jax.numpy as jnp
import numpy as np

import sph
from sph.cases import rpf
from sph.forces import ConstantForce
from sph.lattice import cartesian
from sph.neighbors import make_neighbor_search

GRAPH_SKIN = 0.25
"""Skin of the corrector's Verlet list, relative to the connectivity radius (rebuilt when a particle
moved by half of it; the edges are masked to the radius in `graph_features`)."""


@dataclass(frozen=True, eq=False, repr=False)
class Setup:
    """What the module needs besides its weights: the coarse-substep solver, the graph search, lists
    allocated at a sample frame, and LagrangeBench's normalisation statistics."""

    solver: object
    graph_search: object
    sph_nbrs: object
    graph_nbrs: object
    frame_dt: float
    substeps: int
    radius: float
    vel_mean: jnp.ndarray
    vel_std: jnp.ndarray
    acc_mean: jnp.ndarray
    acc_std: jnp.ndarray
    dtype: object
    data_force: object = None
    extra_inputs: tuple = ()
    start_lag: float = 0.0

    def __repr__(self):  # haiku prints module arguments; never format the (traced) lists
        return f"Setup(substeps={self.substeps}, frame_dt={self.frame_dt:g}, n={self.solver.scene.n})"


def coarse_solver(metadata: dict, substeps: int, dtype: str = "float32", capacity_multiplier: float = 1.5,
                  solver_force: str = "per_particle"):
    """Our SPH solver at the substep delta t = dt * write_every / substeps, with the dataset's
    physics (metadata: dx, viscosity, g_ext_magnitude, p_bg_factor, c_ref_factor); `solver_force`
    "uniform" replaces the data's per-particle RPF force by the authors' (+g, 0) for every particle."""
    dx = float(metadata["dx"])
    g = metadata["g_ext_magnitude"]
    scene = rpf.scene(dx, sph.Material(rho_ref=metadata.get("rho_ref", 1.0), eta=metadata["viscosity"],
                                       u_ref=metadata.get("u_ref", 1.0)),
                      sph.Effects(), r=cartesian([0.0, 0.0], list(rpf.BOX), dx), g=g)
    if solver_force == "uniform":
        scene = dataclasses.replace(scene, body_force=ConstantForce((float(g), 0.0)))
    elif solver_force != "per_particle":
        raise ValueError(f"model.solver_force: {solver_force!r} is not one of per_particle, uniform")
    numerics = sph.Numerics(kernel=metadata.get("kernel", "quintic"), h_factor=metadata.get("h_factor", 1.0),
                            c_ref_factor=metadata["c_ref_factor"], gamma=1.0, p_bg_factor=metadata["p_bg_factor"],
                            dt=metadata["dt"] * metadata["write_every"] / substeps, dtype=dtype,
                            capacity_multiplier=capacity_multiplier)
    with warnings.catch_warnings():
        # the coarse substep exceeds the acoustic CFL limit by design (temporal coarsening, paper
        # Sec. 5): the solver alone is expected to be inaccurate there; that is what SitL corrects
        warnings.filterwarnings("ignore", message=".*exceeds the .* time-step limit")
        return sph.build_solver(scene, numerics)


def make_setup(metadata: dict, normalization_stats: dict, r_sample, substeps: int = 3, dtype: str = "float32",
               capacity_multiplier: float = 1.5, solver_force: str = "per_particle", extra_inputs: tuple = (),
               start: str = "frame_average") -> Setup:
    """Allocate the SPH and graph lists at positions `r_sample` (N, dim), e.g. a training frame
    (the options: settings.Model's solver_force, extra_inputs and start)."""
    solver = coarse_solver(metadata, substeps, dtype, capacity_multiplier, solver_force)
    data_force = (solver if solver_force == "per_particle" else coarse_solver(metadata, substeps, dtype)).scene.body_force
    w = int(metadata["write_every"])
    frame_dt = float(metadata["dt"] * w)
    if start not in ("frame_average", "consistent"):
        raise ValueError(f"model.start: {start!r} is not one of frame_average, consistent")
    jdt = solver.dtype
    radius = float(metadata["default_connectivity_radius"])
    # a Verlet list (skin GRAPH_SKIN radius) from which `graph_features` keeps exactly the pairs closer
    # than the radius at the corrector's input positions: LagrangeBench's graph, no skin edges
    graph = make_neighbor_search(solver.scene.domain, cutoff=radius, skin=GRAPH_SKIN * radius,
                                 capacity_multiplier=capacity_multiplier)
    r = jnp.asarray(r_sample, jdt)
    acc, vel = normalization_stats["acceleration"], normalization_stats["velocity"]
    return Setup(solver=solver, graph_search=graph, sph_nbrs=solver.neighbors.allocate(r), graph_nbrs=graph.allocate(r),
                 frame_dt=frame_dt, substeps=substeps, radius=radius,
                 vel_mean=jnp.asarray(vel["mean"], jdt), vel_std=jnp.asarray(vel["std"], jdt),
                 acc_mean=jnp.asarray(acc["mean"], jdt), acc_std=jnp.asarray(acc["std"], jdt), dtype=jdt,
                 data_force=data_force, extra_inputs=tuple(extra_inputs),
                 start_lag=0.5 * frame_dt * (1.0 - 1.0 / w) if start == "consistent" else 0.0)


def _safe_norm(x):
    d2 = jnp.sum(x * x, axis=-1, keepdims=True)
    pos = d2 > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, d2, 1.0)), 0.0)


def graph_features(setup: Setup, r, u, nbrs) -> dict:
    """LagrangeBench's GNS features at positions r, velocity u (physical): normalised velocity in
    per-frame units, the data's body force (per particle, whatever force the solver uses), and edges (receiver i <- sender j) with displacement / radius
    and its length. The edges are exactly LagrangeBench's graph at r: every pair closer than the
    connectivity radius at r, self edges included (its mask_self=False), nothing of the Verlet
    list's skin (`nbrs`, valid at r, holds a superset; the rest is masked out). Padded and masked
    slots point both ends at N so that jraph's aggregation drops them."""
    n = r.shape[0]
    disp = setup.solver.scene.domain.make_displacement(setup.solver.neighbors.cutoff + setup.solver.neighbors.skin)
    idx = nbrs.idx                                                         # (N, K), padded with N
    senders = jnp.concatenate([idx.reshape(-1), jnp.arange(n)])
    rows = jnp.concatenate([jnp.repeat(jnp.arange(n), idx.shape[1]), jnp.arange(n)])
    rel = disp(r[jnp.minimum(rows, n - 1)], r[jnp.minimum(senders, n - 1)]) / setup.radius
    dist = _safe_norm(rel)
    inside = (senders < n) & (dist[:, 0] < 1.0)
    senders = jnp.where(inside, senders, n)
    receivers = jnp.where(inside, rows, n)
    vel = (u * setup.frame_dt - setup.vel_mean) / setup.vel_std
    return {"vel_hist": vel, "force": setup.data_force(r), "senders": senders, "receivers": receivers,
            "rel_disp": rel, "rel_dist": dist}


def corrector_inputs(setup: Setup, features: dict, a, substep: int) -> dict:
    """The corrector's node inputs with model.extra_inputs appended to LagrangeBench's `force`
    feature (which GNS concatenates with the velocities): "solver_acc", the solver's acceleration a
    in the output's normalised units (a Delta t^2 / sigma_a), and "substep", the index of this
    substep among L, one-hot. Without extras the features are LagrangeBench's own."""
    extra = []
    n = features["vel_hist"].shape[0]
    for name in setup.extra_inputs:
        if name == "solver_acc":
            extra.append(a * setup.frame_dt**2 / setup.acc_std)
        elif name == "substep":
            extra.append(jnp.broadcast_to(jax.nn.one_hot(substep, setup.substeps, dtype=a.dtype), (n, setup.substeps)))
        else:
            raise ValueError(f"model.extra_inputs: {name!r} is not one of solver_acc, substep")
    if not extra:
        return features
    return {**features, "force": jnp.concatenate([features["force"].astype(a.dtype), *extra], axis=-1)}


def edge_set(features: dict, n: int) -> set:
    """{(receiver, sender)} of the real (not padded or masked) edges of a feature dict, ours or
    LagrangeBench's."""
    rec, snd = np.asarray(features["receivers"]), np.asarray(features["senders"])
    keep = (rec < n) & (snd < n)
    return set(zip(rec[keep].tolist(), snd[keep].tolist()))


class SolverInTheLoop(hk.Module):
    """The SitL model (see the module docstring). correction=False is the solver alone: the
    network is never built or evaluated and the module has no parameters."""

    def __init__(self, setup: Setup, correction: bool = True, latent_size: int = 64, blocks_per_step: int = 2,
                 num_mp_steps: int = 10, name: str = "sitl"):
        super().__init__(name=name)
        self.setup = setup
        self.correction = correction
        if correction:
            from lagrangebench import GNS  # only the corrector needs LagrangeBench
            self.gnn = GNS(setup.solver.scene.dim, latent_size, blocks_per_step, num_mp_steps, 16)

    def __call__(self, sample):
        features, particle_type = sample
        s = self.setup
        solver = s.solver
        disp = solver.scene.domain.make_displacement(solver.neighbors.cutoff + solver.neighbors.skin)
        pos = jnp.asarray(features["abs_pos"], s.dtype)
        r0 = pos[:, -1]
        v0 = disp(r0, pos[:, -2])                       # per-frame displacement (LagrangeBench's velocity)
        dt_sub = s.frame_dt / s.substeps
        r, u = r0, v0 / s.frame_dt
        sph_nbrs, graph_nbrs = s.sph_nbrs, s.graph_nbrs
        overflow = jnp.zeros((), bool)
        if s.start_lag:  # model.start "consistent": the velocity at t0, not the last frame's average
            sph_nbrs = solver.neighbors.update(r, sph_nbrs)
            u = u + s.start_lag * solver.state_at(r, u, sph_nbrs).dudt
        for i in range(s.substeps):
            sph_nbrs = solver.neighbors.update(r, sph_nbrs)
            overflow = overflow | sph_nbrs.did_buffer_overflow.astype(bool)
            a = solver.state_at(r, u, sph_nbrs).dudt
            if self.correction:
                graph_nbrs = s.graph_search.update(r, graph_nbrs)
                overflow = overflow | graph_nbrs.did_buffer_overflow.astype(bool)
                features = corrector_inputs(s, graph_features(s, r, u, graph_nbrs), a, i)
                a_n = self.gnn((features, particle_type))["acc"]
                a = a + a_n * s.acc_std / s.frame_dt**2
            u = u + dt_sub * a
            r = solver.scene.domain.shift(r, dt_sub * u)
        acc = (disp(r, r0) - v0 - s.acc_mean) / s.acc_std
        count = hk.get_state("overflow", [], jnp.int32, init=jnp.zeros)
        hk.set_state("overflow", count + overflow.astype(jnp.int32))
        return {"acc": jnp.where(overflow, jnp.nan, acc)}


def build(kind: str, metadata: dict, normalization_stats: dict, r_sample, model_cfg, dtype: str = "float32"):
    """hk.TransformedWithState for `kind` in {"solver", "gns", "sitl"} (model_cfg: settings.Model)."""
    if kind == "gns":
        from lagrangebench import GNS

        def fn(x):
            return GNS(int(metadata["dim"]), model_cfg.latent_dim, model_cfg.num_mlp_layers,
                       model_cfg.num_mp_steps, 16)(x)
    elif kind in ("sitl", "solver"):
        setup = make_setup(metadata, normalization_stats, r_sample, model_cfg.substeps, dtype,
                           model_cfg.capacity_multiplier, model_cfg.solver_force, model_cfg.extra_inputs,
                           model_cfg.start)

        def fn(x):
            return SolverInTheLoop(setup, correction=kind == "sitl", latent_size=model_cfg.latent_dim,
                                   blocks_per_step=model_cfg.num_mlp_layers, num_mp_steps=model_cfg.num_mp_steps)(x)
    else:
        raise ValueError(f"model: {kind!r} is not one of solver, gns, sitl")
    model = hk.without_apply_rng(hk.transform_with_state(fn))
    if kind != "sitl":
        return model

    def init(rng, sample):
        params, state = model.init(rng, sample)
        return zero_last_layer(params), state

    return hk.TransformedWithState(init, model.apply)


def last_layer(params) -> str:
    """The haiku module of the corrector's output layer: the last Linear of the GNS decoder."""
    names = sorted((k for k in params if "_decoder" in k and k.rsplit("/", 1)[-1].startswith("linear")),
                   key=lambda k: int(k.rsplit("_", 1)[-1]) if k.rsplit("_", 1)[-1].isdigit() else 0)
    if not names:
        raise KeyError(f"no decoder Linear among the corrector's parameters {sorted(params)}")
    return names[-1]


def zero_last_layer(params):
    """The corrector's output layer (weights and bias) set to zero, so that the untrained SitL model is
    exactly the solver alone ("no correction" is where training starts; the other layers keep their
    random init, and the gradient reaches them once the last layer is non-zero)."""
    name = last_layer(params)
    return {**params, name: jax.tree_util.tree_map(jnp.zeros_like, params[name])}


def overflowed(state) -> int:
    """Number of SitL forward passes whose in-model lists overflowed (0 for GNS)."""
    leaves = [np.asarray(v) for m in (state or {}).values() for k, v in m.items() if k == "overflow"]
    return int(sum(leaf.sum() for leaf in leaves))
