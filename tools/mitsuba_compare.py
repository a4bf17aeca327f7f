#!/usr/bin/env python3
"""Render Aether scenes with Mitsuba 3 and compare them with ours.

For each scene file: rewrite what Mitsuba 3 no longer accepts, or reads
differently, in a Mitsuba 0.5 file (Aether's own integrator plugins become
Mitsuba's `path`, `ldrfilm` becomes `hdrfilm`, conductors without a
material become copper, Mitsuba 0.5's default; the film size and sample
count are set), render
it with the `scalar_rgb` variant, render the same scene with our path tracer
at the same size and sample count, and print both image means, their
relative difference and the RMSE (from `aether compare`). Mitsuba's images
are written as `<scene>.exr` (the scene's path relative to the scene folder,
with '/' and '.' replaced by '-'), which `reproduce --mitsuba DIR` shows in
its report next to ours, with a false-colour difference image (render with
`--width` equal to the report's).

    pip install mitsuba
    python3 tools/mitsuba_compare.py [--width 128] [--spp 256] [--out target/mitsuba] SCENE.xml ...

Without scene files: cbox_path.xml, cbox-sphere-path-aether.xml and
veach_mi/mi.xml from ../shared/scenes/aether.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.normpath(os.path.join(ROOT, "..", "shared", "scenes", "aether"))
DEFAULT = ["cbox/cbox_path.xml", "cbox-sphere/cbox-sphere-path-aether.xml", "veach_mi/mi.xml"]

# Aether's integrators, and Mitsuba 0.5's own, all become Mitsuba 3's path tracer.
INTEGRATOR_PARAMETERS = {"maxDepth", "rrDepth", "max_depth", "rr_depth"}


def rewrite(path, width, spp):
    """The scene as Mitsuba 3 accepts it, and the film size it renders at."""
    tree = ET.parse(path)
    root = tree.getroot()
    for integrator in root.iter("integrator"):
        integrator.set("type", "path")
        for child in list(integrator):
            if child.get("name") not in INTEGRATOR_PARAMETERS:
                integrator.remove(child)
    # Mitsuba 0.5's conductors are copper unless told otherwise; Mitsuba 3's
    # are perfect mirrors.
    for bsdf in root.iter("bsdf"):
        if bsdf.get("type") in ("conductor", "roughconductor"):
            named = {c.get("name") for c in bsdf}
            if not named & {"material", "eta", "k"}:
                ET.SubElement(bsdf, "string", name="material", value="Cu")
    size = None
    for film in root.iter("film"):
        film.set("type", "hdrfilm")
        values = {c.get("name"): c for c in film if c.tag == "integer"}
        w = int(values["width"].get("value")) if "width" in values else 768
        h = int(values["height"].get("value")) if "height" in values else 576
        height = max(1, round(width * h / w))
        # Only the reconstruction filter is kept: output formats, crop
        # windows and tone mapping do not concern the comparison.
        for child in list(film):
            if child.tag != "rfilter":
                film.remove(child)
        ET.SubElement(film, "integer", name="width", value=str(width))
        ET.SubElement(film, "integer", name="height", value=str(height))
        size = (width, height)
    for sampler in root.iter("sampler"):
        sampler.set("type", "independent")
        for child in list(sampler):
            sampler.remove(child)
        ET.SubElement(sampler, "integer", name="sampleCount", value=str(spp))
    return ET.tostring(root, encoding="unicode"), size


def render_mitsuba(scene, width, spp, out):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    text, size = rewrite(scene, width, spp)
    resolver = mi.Thread.thread().file_resolver()
    resolver.prepend(os.path.dirname(os.path.abspath(scene)))
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
        f.write(text)
    try:
        start = time.time()
        loaded = mi.load_file(f.name)
        image = mi.render(loaded, spp=spp)
        seconds = time.time() - start
        mi.Bitmap(image).write(out)
    finally:
        os.unlink(f.name)
    return size, seconds


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scenes", nargs="*", help="scene files (default: three Aether scenes)")
    p.add_argument("--width", type=int, default=128)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--out", default=os.path.join(ROOT, "target", "mitsuba"))
    p.add_argument("--aether", default=os.path.join(ROOT, "target", "release", "aether"))
    a = p.parse_args()
    scenes = a.scenes or [os.path.join(SCENES, s) for s in DEFAULT]
    os.makedirs(a.out, exist_ok=True)
    if not os.path.exists(a.aether):
        subprocess.run(["cargo", "build", "--release", "-p", "integrators", "--bin", "aether"], cwd=ROOT, check=True)
    rows = []
    for scene in scenes:
        relative = os.path.relpath(os.path.abspath(scene), SCENES)
        stem = re.sub(r"[/.]", "-", relative)
        theirs = os.path.join(a.out, stem + ".exr")
        ours = os.path.join(a.out, stem + "-aether.exr")
        (w, h), seconds = render_mitsuba(scene, a.width, a.spp, theirs)
        subprocess.run([a.aether, "render", scene, "-i", "path", "--spp", str(a.spp), "--width", str(w), "-o", ours],
                       check=True, stdout=subprocess.DEVNULL)
        compared = subprocess.run([a.aether, "compare", theirs, ours], check=True, capture_output=True, text=True).stdout
        m = re.search(r"mean ([0-9.e+-]+) \(reference ([0-9.e+-]+), ([+-][0-9.]+) %\), RMSE ([0-9.e+-]+)", compared)
        if not m:
            sys.exit(f"cannot read the comparison: {compared}")
        rows.append((relative, w, h, float(m.group(2)), float(m.group(1)), float(m.group(3)), float(m.group(4)), seconds))
        print(f"{relative}: Mitsuba 3 {m.group(2)}, ours {m.group(1)} ({m.group(3)} %), RMSE {m.group(4)}", flush=True)
    print(f"\n| scene | size | spp | Mitsuba 3 mean | our mean | difference | RMSE |")
    print("|---|---|---|---|---|---|---|")
    for relative, w, h, mean_m, mean_o, diff, rmse, _ in rows:
        print(f"| {relative} | {w}×{h} | {a.spp} | {mean_m:.5f} | {mean_o:.5f} | {diff:+.2f} % | {rmse:.5f} |")
    if any(abs(r[5]) >= 1.0 for r in rows):
        sys.exit("a mean differs by 1 % or more")


if __name__ == "__main__":
    main()
