#!/usr/bin/env python3
"""Time Mitsuba 3's path tracer on a Mitsuba 0.5 scene; print samples/s.

    python3 tools/peer_bench_mitsuba.py VARIANT SCENE.xml SPP MAX_DEPTH [WIDTH]

The scene is rewritten as tools/mitsuba_compare.py does (its `rewrite`),
with Mitsuba's `path` integrator and `max_depth` MAX_DEPTH (Mitsuba counts
edges, as `aether --max-depth` does). It is loaded, rendered once at 1 spp
(so that the llvm variants compile their kernels outside the timing), then
rendered at SPP; only that render is timed. Prints one line: the samples
per second, WIDTH × height × SPP / seconds. Exits with status 2, saying
why on standard error, if the variant cannot be used.
"""

import os
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mitsuba_compare import rewrite  # noqa: E402


def load(variant, scene, spp, depth, width):
    """Mitsuba 3 (as `variant`) and the scene rewritten for its `path`
    integrator at `max_depth` DEPTH; returns (mi, dr, loaded, (w, h)).
    Exits with status 2, saying why, if the variant cannot be used."""
    try:
        import drjit as dr
        import mitsuba as mi

        mi.set_variant(variant)
    except Exception as e:  # an absent module or a variant that does not load
        print(f"{variant}: {e}", file=sys.stderr)
        sys.exit(2)
    text, size = rewrite(scene, width, spp)
    root = ET.fromstring(text)
    if root.find("integrator") is None:
        root.insert(0, ET.Element("integrator", type="path"))
    for integrator in root.iter("integrator"):
        for child in list(integrator):
            integrator.remove(child)
        ET.SubElement(integrator, "integer", name="max_depth", value=str(depth))
    resolver = mi.file_resolver() if hasattr(mi, "file_resolver") else mi.Thread.thread().file_resolver()
    resolver.prepend(os.path.dirname(os.path.abspath(scene)))
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
        f.write(ET.tostring(root, encoding="unicode"))
    try:
        loaded = mi.load_file(f.name)
    finally:
        os.unlink(f.name)
    return mi, dr, loaded, size


def timed_render(mi, dr, loaded, spp, seed=0):
    """The image of `spp` samples per pixel and the seconds it took, after
    a 1 spp render that compiles the llvm variants' kernels untimed."""
    dr.eval(mi.render(loaded, spp=1, seed=seed + 1))
    dr.sync_thread()
    start = time.perf_counter()
    image = mi.render(loaded, spp=spp, seed=seed)
    dr.eval(image)
    dr.sync_thread()
    return image, time.perf_counter() - start


def main():
    if len(sys.argv) not in (5, 6):
        sys.exit(__doc__)
    variant, scene, spp, depth = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    width = int(sys.argv[5]) if len(sys.argv) == 6 else 512
    mi, dr, loaded, (w, h) = load(variant, scene, spp, depth, width)
    _, seconds = timed_render(mi, dr, loaded, spp)
    print(f"{w * h * spp / seconds:.0f}")


if __name__ == "__main__":
    main()
