"""``ipcsim render OUT``: offscreen PNGs of a run's frames, optionally a GIF or MP4."""

from __future__ import annotations

from pathlib import Path


def main(args) -> int:
    from ..io.render import RenderOptions, parse_frame_range, render_run

    opt = RenderOptions(
        every=args.every,
        frames=parse_frame_range(args.frames) if args.frames else (None, None),
        gif=args.gif,
        mp4=args.mp4,
        field=args.field,
        azimuth=args.azimuth,
        elevation=args.elevation,
        zoom=args.zoom,
        size=tuple(args.size),
        output=Path(args.output) if args.output else None,
    )
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    result = render_run(Path(args.folder), opt, say=say, planes=_run_planes(args.folder, say))
    pngs = result["pngs"]
    say(f"rendered {len(pngs)} frames into {pngs[0].parent}")
    if result["gif"]:
        say(f"animation: {result['gif']} (written with {result['gif_writer']})")
    if result["mp4"]:
        say(f"video: {result['mp4']}")
    return 0


def _run_planes(folder, say) -> list:
    """The planes of the run's scene (its ``scene.toml``), to draw with the frames."""
    from ..scene import load_scene

    scene_path = Path(folder) / "scene.toml"
    if scene_path.is_file():
        return list(load_scene(scene_path).planes)
    say(f"warning: {scene_path} not found; planes are not drawn")
    return []
