"""``ipcsim convert SOURCE TARGET``: translate a scene between the IPC script format
(.txt/.ipc) and TOML, by the extensions. The target holds the fully resolved scene (every
default written out, mesh paths relative to the target's folder)."""

from __future__ import annotations

import sys

from ..scene import load_scene, save_scene, scene_format


def main(args) -> int:
    scene_format(args.target)  # refuse an unknown target extension before reading anything
    spec = load_scene(args.source)
    for warning in spec.warnings:
        print(warning, file=sys.stderr)
    path = save_scene(spec, args.target)
    n = len(spec.shapes)
    print(f"wrote {path} ({n} shape{'s' if n != 1 else ''}, {len(spec.planes)} plane"
          f"{'s' if len(spec.planes) != 1 else ''}, {len(spec.mesh_obstacles)} mesh "
          f"obstacle{'s' if len(spec.mesh_obstacles) != 1 else ''})")
    return 0
