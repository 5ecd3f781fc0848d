"""``ipcsim convert SOURCE TARGET``: translate a scene between the IPC script format
(.txt/.ipc) and TOML, by the extensions. The target holds the fully resolved scene (every
default written out, mesh paths relative to the target's folder). It is never the source
itself (a scene's comments would be lost), and an existing target is replaced only with
``--overwrite``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..errors import SceneError
from ..scene import load_scene, save_scene, scene_format


def _same_file(a: Path, b: Path) -> bool:
    if os.path.normpath(os.path.abspath(a)) == os.path.normpath(os.path.abspath(b)):
        return True
    try:
        return b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def main(args) -> int:
    source, target = Path(args.source), Path(args.target)
    scene_format(target)  # refuse an unknown target extension before reading anything
    if _same_file(source, target):
        raise SceneError(target, None, "is the source itself; converting a scene onto "
                                       "itself would lose its comments: name another file")
    if target.is_dir():
        raise SceneError(target, None, "is a folder, not a scene file")
    if target.exists() and not getattr(args, "overwrite", False):
        raise SceneError(target, None, "exists; pass --overwrite to replace it")
    spec = load_scene(source)
    for warning in spec.warnings:
        print(warning, file=sys.stderr)
    path = save_scene(spec, target)
    n = len(spec.shapes)
    print(f"wrote {path} ({n} shape{'s' if n != 1 else ''}, {len(spec.planes)} plane"
          f"{'s' if len(spec.planes) != 1 else ''}, {len(spec.mesh_obstacles)} mesh "
          f"obstacle{'s' if len(spec.mesh_obstacles) != 1 else ''})")
    return 0
