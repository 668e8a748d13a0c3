"""Time to rest of one drape in drape and in NVIDIA Newton's VBD solver, in one run.

The drape is an example at N x N (`--scene sphere`: `examples/drape_sphere.json`; `--scene
tablecloth`: `examples/tablecloth.json` without its own solver settings) run as a user runs it:
`drape run` of the scene at `--drape-dt` (1/60 s; a number or a fraction) with `stop_at_rest`
0.005 and the final frame only, its default error estimate included. Newton then runs the same
sheet with its own triangles and hinges (`newton_drape.py --model triangles`) at 1/60 s, the step
it is stable at, to rest or to `--max-time`. Newton's rest is judged after every step, drape's
every 1/30 s of simulated time, so drape may find its rest up to that late; either can stop in
a lull, which only a longer run shows (`docs/performance.md`, "Time to rest against Newton, on
the sphere").

It prints one JSON line per run and then the ratio of Newton's wall time to drape's, for drape's run
alone and for the whole command with its error estimate: to rest when both rest, or to
`--max-time` when Newton does not (a lower bound, then); none when drape does not rest. `drape` is
the release binary at `target/release/drape`, which the script first builds from the working tree
(`cargo build --release --locked --bin drape`), so that a binary left there by another checkout
is never the one measured.

    python3 -m venv .venv-newton
    .venv-newton/bin/pip install newton==1.8.0 warp-lang==1.19.0
    .venv-newton/bin/python benches/peers/time_to_rest.py --scene sphere --max-time 40 --drape-dt 1/600
"""

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time

import warp as wp

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import newton_drape  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = {"sphere": "drape_sphere.json", "tablecloth": "tablecloth.json"}
NEWTON_DT = 1 / 60


def seconds(text):
    """A step in seconds, as a number or a fraction: `0.01`, `1/600`."""
    numerator, _, denominator = text.partition("/")
    return float(numerator) / float(denominator or 1)


def drape_scene(scene, n, dt, max_time):
    """The example at n x n, stepped at dt until at rest or max_time, recording its final frame."""
    s = json.loads((ROOT / "examples" / EXAMPLES[scene]).read_text())
    s.pop("solver", None)
    s["bodies"][0]["resolution"] = [n, n]
    s.update(dt=dt, duration=max_time, stop_at_rest=newton_drape.REST_SPEED)
    s["output"] = {"frames": "final", "fields": ["positions"]}
    return s


def run_drape(scene, n, dt, max_time):
    with tempfile.TemporaryDirectory() as tmp:
        scene_file, result_file = pathlib.Path(tmp, "scene.json"), pathlib.Path(tmp, "result.json")
        scene_file.write_text(json.dumps(drape_scene(scene, n, dt, max_time)))
        start = time.perf_counter()
        subprocess.run([ROOT / "target/release/drape", "run", "-q", scene_file, "-o", result_file], check=True)
        command = time.perf_counter() - start
        result = json.loads(result_file.read_text())
    stats, positions = result["stats"], result["final"]["positions"]
    rest = stats.get("stopped_at_rest")
    return dict(peer="drape", scene=scene, n=n, dt=dt, steps=stats["steps"], at_rest=rest is not None,
                simulated_s=rest if rest is not None else stats["steps"] * dt, wall_s=stats["wall_time_s"],
                command_s=command, cg_per_step=stats["linear_solver"]["mean_iterations"],
                lowest_y=min(positions[1::3]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", choices=sorted(EXAMPLES), default="sphere")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--max-time", type=float, default=40.0)
    ap.add_argument("--drape-dt", type=seconds, default=NEWTON_DT)
    args = ap.parse_args()
    subprocess.run(["cargo", "build", "--release", "--locked", "--bin", "drape"], cwd=ROOT, check=True)
    drape = run_drape(args.scene, args.n, args.drape_dt, args.max_time)
    print(json.dumps(drape), flush=True)
    wp.init()
    newton = newton_drape.run(args.scene, args.n, NEWTON_DT, newton_drape.RADIUS, newton_drape.CONTACT_KE,
                              newton_drape.ITERATIONS, args.max_time, "triangles")
    print(json.dumps(newton), flush=True)
    if not drape["at_rest"]:
        print(json.dumps(dict(ratio=None, why=f"drape is not at rest by {args.max_time} s")))
        return
    bound = "" if newton["at_rest"] else "at least "
    print(json.dumps(dict(ratio=f"{bound}{newton['wall_s'] / drape['wall_s']:.1f}",
                          ratio_with_estimate=f"{bound}{newton['wall_s'] / drape['command_s']:.1f}")))


if __name__ == "__main__":
    main()
