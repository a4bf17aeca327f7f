#!/usr/bin/env python3
"""Equal-time quality against Mitsuba 3: is our path tracer's speed bought with noise?

    PYTHON tools/peer_quality.py [--scene S] [--width W] [--spp N] [--depth D]
                                 [--reference-spp R] [--runs K] [--variant V]

Both renderers path-trace the scene (default ../shared/scenes/aether/cbox/
cbox_path.xml, 256 wide, 16 spp, max depth 6) K times with different seeds,
taking turns. Each image's RMSE is measured by `aether compare` against one
converged reference, rendered once by our path tracer at R spp (default
1024) and kept in target/peer (the two renderers' image means agree to
0.1 % on this scene, README; the script prints Mitsuba's against it too).
Reported: median seconds of the render alone (no scene loading), median
RMSE, and the inefficiency MSE × seconds, whose ratio says which renderer
reaches a given error sooner: for an unbiased estimator MSE falls as
1/time, so Mitsuba's inefficiency over ours is how many times longer
Mitsuba takes for our error (≥ 1: ours is at least as good at equal time).
The reference's own noise (1/R of a sample's variance against 1/N in the
renders) adds N/R to both MSEs alike.

PYTHON is a Python that imports mitsuba (tools/peer_bench.sh says how to get
one). AETHER (environment) is our program, default target/release/aether.
"""

import argparse
import os
import re
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_bench_mitsuba import load, timed_render  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def ours(aether, scene, width, spp, depth, seed, out):
    """Renders with our path tracer; returns the seconds it printed."""
    run = subprocess.run(
        [aether, "render", scene, "-i", "path", "--spp", str(spp), "--max-depth", str(depth),
         "--width", str(width), "--seed", str(seed), "-o", out],
        capture_output=True, text=True, check=True,
    )
    found = re.search(r": ([0-9.]+) s, ", run.stdout + run.stderr)
    if not found:
        sys.exit(f"no render time in aether's output:\n{run.stdout}{run.stderr}")
    return float(found.group(1))


def rmse(aether, reference, image):
    """RMSE of `image` against `reference`, and its mean's difference, by `aether compare`."""
    run = subprocess.run([aether, "compare", reference, image], capture_output=True, text=True, check=True)
    found = re.search(r", ([-+][0-9.]+) %\), RMSE ([0-9.]+)", run.stdout)
    if not found:
        sys.exit(f"cannot read aether compare's output:\n{run.stdout}{run.stderr}")
    return float(found.group(2)), float(found.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=os.path.join(ROOT, "../shared/scenes/aether/cbox/cbox_path.xml"))
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--depth", type=int, default=6)
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    aether = os.environ.get("AETHER", os.path.join(ROOT, "target/release/aether"))
    out = os.path.join(ROOT, "target/peer")
    os.makedirs(out, exist_ok=True)
    name = os.path.splitext(os.path.basename(args.scene))[0]

    reference = os.path.join(out, f"{name}-{args.width}-d{args.depth}-ref{args.reference_spp}.exr")
    if not os.path.exists(reference):
        print(f"rendering the reference, {args.reference_spp} spp: {reference}", flush=True)
        ours(aether, args.scene, args.width, args.reference_spp, args.depth, 12345, reference)

    mi, dr, loaded, _ = load(args.variant, args.scene, args.spp, args.depth, args.width)
    rows = {"ours": [], f"mitsuba-{args.variant}": []}
    for k in range(args.runs):
        image = os.path.join(out, f"{name}-ours-{k}.exr")
        seconds = ours(aether, args.scene, args.width, args.spp, args.depth, k, image)
        rows["ours"].append((seconds, *rmse(aether, reference, image)))
        picture, seconds = timed_render(mi, dr, loaded, args.spp, seed=k)
        image = os.path.join(out, f"{name}-mitsuba-{k}.exr")
        mi.Bitmap(picture).write(image)
        rows[f"mitsuba-{args.variant}"].append((seconds, *rmse(aether, reference, image)))
        for who, r in rows.items():
            print(f"  run {k + 1}/{args.runs} {who}: {r[-1][0]:.3f} s, RMSE {r[-1][1]:.5f}, mean {r[-1][2]:+.3f} %",
                  flush=True)

    print(f"\n{name}, {args.width} wide, {args.spp} spp, max depth {args.depth}; "
          f"reference {args.reference_spp} spp; medians of {args.runs}")
    print(f"{'renderer':24} {'seconds':>9} {'RMSE':>9} {'MSE x s':>11} {'mean vs ref':>12}")
    inefficiency = {}
    for who, r in rows.items():
        t = statistics.median(x[0] for x in r)
        e = statistics.median(x[1] for x in r)
        m = statistics.median(x[2] for x in r)
        inefficiency[who] = e * e * t
        print(f"{who:24} {t:9.3f} {e:9.5f} {e * e * t:11.3e} {m:+11.3f} %")
    ratio = inefficiency[f"mitsuba-{args.variant}"] / inefficiency["ours"]
    print(f"Mitsuba's MSE x seconds over ours: {ratio:.2f} (>= 1: ours at least as good at equal time)")


if __name__ == "__main__":
    main()
