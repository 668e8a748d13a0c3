"""Time to rest of a drape at N x N in NVIDIA Newton's VBD solver (CPU).

`--scene sphere` (the default) is `examples/drape_sphere.json`, the peer of
`cargo bench --bench time_to_drape -- grid` (drape's implicit Euler at 1/60 s): the same sheet
(1 m x 1 m, 0.4 kg, horizontal at y = 1, released at rest), the same spring families and
constants per spring (structural 2000 N/m and 2 N s/m, shear 200 and 0.2, bending two apart 20
and 0.02), the same drag (0.2 per second, a force of -0.2 m v), the sphere (centre (0, 0.5, 0),
radius 0.3) and the floor (y = 0), friction 0.5 on both. `--scene tablecloth` is
`examples/tablecloth.json` in the same way: a 1.2 m sheet of 0.5 kg at y = 0.8, springs 3000,
300 and 20 N/m, drag 1 per second, over a round table (radius 0.4 m, height 0.7 m) on the floor,
friction 0.6. Newton's VBD solves implicit Euler by vertex block descent with `--iterations`
sweeps per step; its contacts are penalty forces (`--contact-ke`) on particles of radius
`--radius`.

The run is at rest when, after the sheet has begun to move, no particle is faster than 0.005 m/s
(drape's `stop_at_rest`). It prints one JSON line per dt: steps, simulated time and wall time to
rest (kernel compilation excluded: a first step on a throwaway state compiles them), whether it
stayed finite, the fastest particle's speed at the end, and the sheet's lowest point.

    python3 -m venv .venv-newton
    .venv-newton/bin/pip install newton==1.8.0 warp-lang==1.19.0
    .venv-newton/bin/python benches/peers/newton_drape.py --n 128 --dt 0.016667 0.004167
    .venv-newton/bin/python benches/peers/newton_drape.py --scene tablecloth --n 128 \
        --model triangles --max-time 12
"""

import argparse
import json
import time

import numpy as np
import warp as wp

wp.config.quiet = True
import newton  # noqa: E402

REST_SPEED = 0.005
# The solver's settings unless the command line gives others: VBD iterations a step, the
# particles' contact radius (m) and the contact stiffness (N/m).
ITERATIONS = 10
RADIUS = 0.004
CONTACT_KE = 1.0e4
# Contacts are looked for this far beyond a particle's radius: more than a falling sheet travels
# in a step at 1/60 s, so that none passes a surface between two queries.
CONTACT_GAP = 0.1
SCENES = {
    "sphere": dict(size=1.0, height=1.0, mass=0.4, drag=0.2, mu=0.5,
                   springs=dict(structural=(2000.0, 2.0), shear=(200.0, 0.2), bending=(20.0, 0.02))),
    "tablecloth": dict(size=1.2, height=0.8, mass=0.5, drag=1.0, mu=0.6,
                       springs=dict(structural=(3000.0, 2.0), shear=(300.0, 0.3), bending=(20.0, 0.05))),
}


def families(springs):
    """Offset -> (k, damping), per spring."""
    return {
        (1, 0): springs["structural"], (0, 1): springs["structural"],
        (1, 1): springs["shear"], (1, -1): springs["shear"],
        (2, 0): springs["bending"], (0, 2): springs["bending"],
    }


@wp.kernel
def drag_force(qd: wp.array(dtype=wp.vec3), drag: wp.array(dtype=float), f: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    f[i] = -drag[i] * qd[i]


def build(scene, n, radius, contact_ke, iterations, model_kind):
    sc = SCENES[scene]
    size, height = sc["size"], sc["height"]
    b = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
    shape = b.default_shape_cfg.copy()
    shape.mu = sc["mu"]
    b.add_ground_plane(cfg=shape)
    if scene == "sphere":
        b.add_shape_sphere(-1, xform=wp.transform((0.0, 0.5, 0.0), wp.quat_identity()), radius=0.3, cfg=shape)
    else:
        # Newton's cylinders lie along z; turned a quarter about x, along y.
        upright = wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), -wp.pi * 0.5)
        b.add_shape_cylinder(-1, xform=wp.transform((0.0, 0.35, 0.0), upright), radius=0.4, half_height=0.35, cfg=shape)
    m = sc["mass"] / (n * n)
    structural_k, bending_k = sc["springs"]["structural"][0], sc["springs"]["bending"][0]
    if model_kind == "springs":
        grid = [(i, j) for j in range(n) for i in range(n)]
        positions = [((i / (n - 1) - 0.5) * size, height, (j / (n - 1) - 0.5) * size) for i, j in grid]
        b.add_particles(pos=positions, vel=[(0.0, 0.0, 0.0)] * (n * n), mass=[m] * (n * n), radius=[radius] * (n * n))
        for i, j in grid:
            for (di, dj), (k, c) in families(sc["springs"]).items():
                if 0 <= i + di < n and 0 <= j + dj < n:
                    b.add_spring(j * n + i, (j + dj) * n + i + di, k, c, 0.0)
    else:
        # VBD's own cloth: linear triangles and hinges. A spring family of stiffness k per spring
        # gives the sheet a membrane stiffness of k per unit strain and width, whatever the
        # resolution; the triangles get the structural springs' (shared between the two Lamé
        # terms), the hinges the bending springs' k times the square of their length.
        spacing = size / (n - 1)
        b.add_cloth_grid(pos=wp.vec3(-0.5 * size, height, -0.5 * size),
                         rot=wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), wp.pi * 0.5),
                         vel=wp.vec3(0.0, 0.0, 0.0), dim_x=n - 1, dim_y=n - 1, cell_x=spacing, cell_y=spacing, mass=m,
                         tri_ke=0.5 * structural_k, tri_ka=0.5 * structural_k, tri_kd=1.0e-3,
                         edge_ke=bending_k * (2 * spacing) ** 2, edge_kd=1.0e-4, particle_radius=radius)
    b.color(include_bending=model_kind != "springs")
    model = b.finalize(device="cpu")
    model.particle_grid = None
    model.soft_contact_ke = contact_ke
    model.soft_contact_kd = 0.0
    model.soft_contact_mu = sc["mu"]
    solver = newton.solvers.SolverVBD(model, iterations=iterations)
    drag = wp.array(np.full(n * n, sc["drag"] * m), dtype=float, device="cpu")
    return model, solver, drag


def run(scene, n, dt, radius, contact_ke, iterations, max_time, model_kind):
    model, solver, drag = build(scene, n, radius, contact_ke, iterations, model_kind)
    pipeline = newton.CollisionPipeline(model, soft_contact_gap=CONTACT_GAP)
    contacts = pipeline.contacts()
    control = model.control()

    def step(s0, s1):
        wp.launch(drag_force, model.particle_count, inputs=[s0.particle_qd, drag], outputs=[s0.particle_f], device="cpu")
        pipeline.collide(s0, contacts)
        solver.step(s0, s1, control, contacts, dt)

    step(model.state(), model.state())  # compiles the kernels
    wp.synchronize()
    s0, s1 = model.state(), model.state()
    steps, moved, at_rest, finite, speed = 0, False, False, True, 0.0
    start = time.perf_counter()
    while steps * dt < max_time:
        step(s0, s1)
        s0, s1 = s1, s0
        steps += 1
        speed = float(np.sqrt((s0.particle_qd.numpy() ** 2).sum(axis=1)).max())
        if not np.isfinite(speed):
            finite = False
            break
        moved = moved or speed > 10 * REST_SPEED
        if moved and speed < REST_SPEED:
            at_rest = True
            break
    wall = time.perf_counter() - start
    q = s0.particle_q.numpy()
    return dict(peer="newton_vbd", newton=newton.__version__, scene=scene, model=model_kind, n=n, dt=dt, iterations=iterations, radius=radius,
                contact_ke=contact_ke, steps=steps, simulated_s=steps * dt, wall_s=wall, at_rest=at_rest,
                finite=finite, fastest_at_end=speed, lowest_y=float(q[:, 1].min()) if finite else None)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", choices=sorted(SCENES), default="sphere")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--dt", type=float, nargs="*", default=[1 / 60])
    ap.add_argument("--iterations", type=int, default=ITERATIONS)
    ap.add_argument("--radius", type=float, default=RADIUS)
    ap.add_argument("--contact-ke", type=float, default=CONTACT_KE)
    ap.add_argument("--max-time", type=float, default=5.0)
    ap.add_argument("--model", choices=["springs", "triangles"], default="springs")
    args = ap.parse_args()
    wp.init()
    for dt in args.dt:
        print(json.dumps(run(args.scene, args.n, dt, args.radius, args.contact_ke, args.iterations, args.max_time, args.model)), flush=True)


if __name__ == "__main__":
    main()
